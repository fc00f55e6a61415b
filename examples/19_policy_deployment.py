"""Deploy a policy the way DROID-trained ones act, under DROID's contract: chunks of 10
actions (7 normalised joint velocities, 1 = 0.2 rad a step, and a gripper command, 0 open,
1 closed) at 15 Hz, 8 of each run open loop before the policy is asked again (openpi's
``open_loop_horizon``), followed as DROID's robots follow them. Here the "policy" is
scripted: it steers the joints toward a goal above the table and closes the hand once
there, then back to the start with the hand open. Each episode, with the camera's images
(a simulated robot's), is recorded to an HDF5 file in robomimic's layout, or with
``--format lerobot`` to a LeRobot dataset (its images as AV1 video), and read back."""

import numpy as np
from _robot import connect, robot_host

from panda_py.learning import (
    DroidActions,
    EpisodeWriter,
    LeRobotWriter,
    PolicyRunner,
    read_lerobot,
    read_recording,
)
from panda_py.learning.droid import DROID_MAX_JOINT_DELTA
from panda_py.libfranka import Gripper

RATE = 15.0  # [Hz] DROID's
CHUNK, HORIZON = 10, 8  # actions a chunk, of which run before the next call
STEP = 0.1  # [rad] the largest joint move an action asks for (0.5 normalised)
# of an action's move, the share DROID's soft controller covers before the next action (a
# cautious guess: the chunk's later actions ask for the rest of the way from where the
# arm will be; guessing more leaves the arm short when the chunk ends)
FOLLOWED = 0.3
GOAL = np.array([0.35, 0.1, -0.25, -2.0, 0.05, 2.1, 1.0])  # [rad] over the table
CAMERA = (320, 180)  # [px] DROID's recorded image size (its RLDS release)


def reaching_policy(goal, close):
    """A scripted policy: a chunk of DROID actions toward ``goal``. Each action is a move
    from where the arm will be then (DROID integrates from the measured joints): the rest
    of the way, at most ``STEP``, normalised (1 = 0.2 rad); with ``close``, the hand closes
    within 0.03 rad of the goal (1 = closed), otherwise it opens."""

    def policy(obs):
        q = obs["observation/joint_position"].copy()
        chunk = np.zeros((CHUNK, 8))
        for i in range(CHUNK):
            move = np.clip(goal - q, -STEP, STEP)  # [rad]
            chunk[i, :7] = move / DROID_MAX_JOINT_DELTA
            q += FOLLOWED * move
            chunk[i, 7] = float(close and np.abs(goal - q).max() < 0.03)
        return chunk

    return policy


def options(parser):
    parser.add_argument(
        "--format",
        default="hdf5",
        choices=["hdf5", "lerobot"],
        help="robomimic's HDF5 file, or a LeRobot dataset (a directory)",
    )
    parser.add_argument("--out", help="the recording (default: episodes.hdf5, episodes_lerobot)")
    parser.add_argument("--steps", type=int, default=60, help="policy steps an episode")


if __name__ == "__main__":
    with robot_host(__doc__, options=options, camera=CAMERA) as (hostname, args):
        panda = connect(hostname)
        gripper = Gripper(hostname)
        panda.move_to_start()
        start = panda.q
        # a real robot: pass your cameras here, e.g. {"wrist_image_left": zed.read}
        cameras = {"exterior_image_1_left": args.render} if args.render else {}
        meta = {"env_kwargs": {"robot": args.robot, "action_space": "joint_velocity",
                               "rate": RATE}}  # fmt: skip
        lerobot = args.format == "lerobot"
        out = args.out or ("episodes_lerobot" if lerobot else "episodes.hdf5")
        if lerobot:  # a new directory, written whole when the recorder closes
            recorder = LeRobotWriter(out, fps=int(RATE), env_args=meta)
        else:
            recorder = EpisodeWriter(out, env_args=meta)
        with (
            recorder,
            DroidActions(panda, gripper, cameras=cameras) as arm,
        ):
            for prompt, goal, close in (("reach and close", GOAL, True),
                                        ("back and open", start, False)):  # fmt: skip
                recorder.begin(prompt=prompt)
                runner = PolicyRunner(arm, reaching_policy(goal, close), replan_every=HORIZON,
                                      prompt=prompt, recorder=recorder)  # fmt: skip
                stats = runner.run(args.steps)
                n = recorder.end()
                off = np.abs(panda.q - goal).max()
                print(f"episode {n} ({prompt}): {stats.summary()}; {off:.3f} rad from the "
                      f"goal, hand {gripper.read_once().width * 1000:.0f} mm")  # fmt: skip
        panda.move_to_start()

        recording = read_lerobot(out) if lerobot else read_recording(out)
        steps = sum(len(e) for e in recording.episodes)
        frames = [e.obs.get("exterior_image_1_left") for e in recording.episodes]
        shape = "no" if frames[0] is None else "x".join(map(str, frames[0].shape[1:3]))
        print(f"recorded {len(recording.episodes)} episodes, {steps} steps, {shape} frames to "
              f"{out}; actions {recording.episodes[0].actions.shape[1]}-wide, obs: "
              f"{', '.join(sorted(recording.episodes[0].obs))}")  # fmt: skip
        gripper.close()
        panda.close()
