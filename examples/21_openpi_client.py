"""openpi's own client, end to end: a policy served over openpi's websocket protocol
(``PolicyServer``, here a scripted stand-in for pi0-FAST-DROID or pi0.5-DROID), called by
openpi's ``WebsocketClientPolicy`` with the request its DROID client sends (two camera
images resized to 224x224 with ``image_tools.resize_with_pad``, the joint and gripper
positions, the prompt), and the chunks it returns run on the robot by ``PolicyRunner``:
10 actions of DROID's normalised joint velocities (1 = 0.2 rad a 1/15 s step) and a
gripper command, 8 of each run before the next request.

Needs ``openpi-client``, which pins numpy<2: install it into an environment of its own
beside this package (``pip install openpi-client panda-py-pure[learning] "numpy<2"``)."""

import sys

import numpy as np
from _robot import connect, robot_host

from panda_py.learning import DroidActions, PolicyRunner, PolicyServer
from panda_py.learning.droid import DROID_MAX_JOINT_DELTA
from panda_py.libfranka import Gripper

try:
    from openpi_client import image_tools, websocket_client_policy
except ImportError:
    sys.exit("This example needs openpi's client: pip install openpi-client (numpy<2)")

RATE = 15.0  # [Hz] DROID's
CHUNK, HORIZON = 10, 8  # actions a chunk, of which run before the next request
IMAGE = 224  # [px] what openpi's DROID client resizes the images to (examples/droid/main.py)
CAMERA = (320, 180)  # [px] DROID's recorded image size (its RLDS release)
STEP = 0.1  # [rad] the largest joint move an action asks for (0.5 normalised)
# of an action's move, the share DROID's soft controller covers before the next action (a
# cautious guess: the chunk's later actions ask for the rest of the way from there)
FOLLOWED = 0.3
GOAL = np.array([0.35, 0.1, -0.25, -2.0, 0.05, 2.1, 1.0])  # [rad] over the table
PROMPT = "reach over the table and close the hand"
# what openpi's DROID client sends, no more
REQUEST = {"observation/exterior_image_1_left", "observation/wrist_image_left",
           "observation/joint_position", "observation/gripper_position", "prompt"}  # fmt: skip


def stand_in_policy(goal, seen):
    """The served policy, a stand-in for a learned one: checks the request is what
    openpi's DROID client sends, then answers ``{"actions": (10, 8)}`` steering the joints
    toward ``goal`` in DROID's normalised velocities, the hand closing (1) within 0.03 rad
    of it. ``seen`` counts the requests and collects their images' shapes.

    Each action is a move from where the arm will be then (DROID integrates from the
    measured joints): the rest of the way, at most ``STEP``; DROID's soft gains against the
    joints' friction leave the arm some mrad short (a learned policy closes that loop on
    what it sees)."""

    def policy(obs):
        if set(obs) != REQUEST:
            raise ValueError(f"expected openpi's DROID request {sorted(REQUEST)}, got "
                             f"{sorted(obs)}")  # fmt: skip
        for key in ("observation/exterior_image_1_left", "observation/wrist_image_left"):
            image = obs[key]
            if image.shape != (IMAGE, IMAGE, 3) or image.dtype != np.uint8:
                raise ValueError(f"{key}: expected ({IMAGE}, {IMAGE}, 3) uint8, got "
                                 f"{image.shape} {image.dtype}")  # fmt: skip
            seen["images"].add(f"{'x'.join(map(str, image.shape))} {image.dtype}")
        seen["requests"] += 1
        seen["prompts"].add(obs["prompt"])
        q = obs["observation/joint_position"].astype(np.float64)  # (read-only as received)
        chunk = np.zeros((CHUNK, 8))
        for i in range(CHUNK):
            move = np.clip(goal - q, -STEP, STEP)  # [rad]
            chunk[i, :7] = move / DROID_MAX_JOINT_DELTA  # normalised: [-1, 1]
            q = q + FOLLOWED * move
            chunk[i, 7] = float(np.abs(goal - q).max() < 0.03)
        return {"actions": chunk}

    return policy


def droid_client(client):
    """The policy as openpi's DROID client calls it (examples/droid/main.py): the request
    built from the robot's observation, images resized with padding on this side."""

    def policy(obs):
        exterior = obs["observation/exterior_image_1_left"]
        # the simulator has one camera: it stands in for the wrist camera too
        wrist = obs.get("observation/wrist_image_left", exterior)
        resize = image_tools.resize_with_pad
        request = {
            "observation/exterior_image_1_left": resize(exterior, IMAGE, IMAGE),
            "observation/wrist_image_left": resize(wrist, IMAGE, IMAGE),
            "observation/joint_position": obs["observation/joint_position"],
            "observation/gripper_position": obs["observation/gripper_position"],
            "prompt": obs["prompt"],
        }
        return client.infer(request)  # {"actions": (10, 8), "server_timing": ...}

    return policy


if __name__ == "__main__":
    with robot_host(__doc__, camera=CAMERA) as (hostname, args):
        panda = connect(hostname)
        gripper = Gripper(hostname)
        panda.move_to_start()
        # a real robot: pass your cameras here, e.g. {"exterior_image_1_left": zed.read,
        # "wrist_image_left": wrist.read}
        blank = np.zeros((CAMERA[1], CAMERA[0], 3), np.uint8)
        cameras = {"exterior_image_1_left": args.render or (lambda: blank)}
        seen = {"requests": 0, "images": set(), "prompts": set()}
        meta = {"policy": "stand-in reaching", "action_horizon": CHUNK}
        with PolicyServer(stand_in_policy(GOAL, seen), port=0, metadata=meta) as server:
            client = websocket_client_policy.WebsocketClientPolicy("127.0.0.1", server.port)
            print(f"openpi's client connected to {server.url}: {client.get_server_metadata()}")
            with DroidActions(panda, gripper, cameras=cameras) as arm:  # DROID's contract
                runner = PolicyRunner(arm, droid_client(client), replan_every=HORIZON,
                                      prompt=PROMPT)  # fmt: skip
                stats = runner.run(60)
        off = np.abs(panda.q - GOAL).max()
        print(f"openpi client: {stats.summary()}; {off:.3f} rad from the goal, hand "
              f"{gripper.read_once().width * 1000:.0f} mm")  # fmt: skip
        print(f"the server answered {seen['requests']} requests, frames "
              f"{', '.join(sorted(seen['images']))} (from {CAMERA[0]}x{CAMERA[1]} camera "
              f"images), prompt {', '.join(map(repr, sorted(seen['prompts'])))}; a request "
              f"took {np.mean(stats.policy_seconds) * 1000:.1f} ms")  # fmt: skip
        panda.move_to_start()
        gripper.close()
        panda.close()
