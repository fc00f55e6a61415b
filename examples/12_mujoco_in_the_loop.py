"""MuJoCo with the robot in the loop: a MuJoCo scene mirrors the robot's measured joint
positions (and can record it), and the same model predicts where the arm will be 10 ms
later (by the robot's clock) from the measured state and the commanded torques.

``--record frames.png`` renders the mirrored scene offscreen (set ``MUJOCO_GL=egl`` on a
machine without a display) and saves a strip of frames (needs matplotlib)."""

import mujoco
import numpy as np
from _robot import connect, robot_host

from panda_py import controllers
from panda_py.robots.mjcf import build_model

RATE = 100  # [Hz] mirror and predict this often
FRAME_EVERY = 0.5  # [s] of the loop's time between recorded frames (the first at once)


def options(parser):
    parser.add_argument("--record", help="save a strip of rendered frames to this PNG")
    parser.add_argument("--runtime", type=float, default=4.0, help="[s]")


if __name__ == "__main__":
    with robot_host(__doc__, options=options, paced=True) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()

        # the robot as MuJoCo sees it: panda_py's model of the arm and hand, with a table
        model = build_model(args.robot, hand=True, scene=True)  # --robot fr3 for an FR3
        model.opt.timestep = 1.0 / 1000
        arm = [model.joint(f"joint{i}") for i in range(1, 8)]
        qpos = np.array([j.qposadr[0] for j in arm])
        dof = np.array([j.dofadr[0] for j in arm])
        mirror, predict = mujoco.MjData(model), mujoco.MjData(model)
        renderer = mujoco.Renderer(model, 240, 320) if args.record else None
        camera = mujoco.MjvCamera()  # looking at the arm from the front left
        camera.lookat[:], camera.distance, camera.azimuth, camera.elevation = (
            (0.3, 0.0, 0.35), 1.6, 150.0, -20.0)  # fmt: skip
        frames = []

        # something to watch: the end effector swings along y (as in 06)
        ctrl = controllers.CartesianImpedance()
        x0, q0 = panda.get_position(), panda.get_orientation()
        panda.start_controller(ctrl)
        errors, naive, last = [], [], None
        with panda.create_context(frequency=RATE, max_runtime=args.runtime) as ctx:
            while ctx.ok():
                ctrl.set_control(x0 + np.array([0, 0.1 * np.sin(ctrl.get_time()), 0]), q0)
                state = panda.get_state()
                # mirror: the scene takes the measured joint positions
                mirror.qpos[qpos] = state.q
                mujoco.mj_forward(model, mirror)
                if renderer is not None and ctx.time >= len(frames) * FRAME_EVERY:
                    renderer.update_scene(mirror, camera)
                    frames.append(renderer.render())
                # predict: from the last measured q, dq and commanded torques, step the model
                # over the robot time that passed since, and compare with what was measured
                if last is not None:
                    steps = round(state.time.to_msec() - last.time.to_msec())
                    predict.qpos[qpos], predict.qvel[dof] = last.q, last.dq
                    predict.qfrc_applied[dof] = last.tau_J_d  # gravity-free, like the model
                    for _ in range(steps):
                        mujoco.mj_step(model, predict)
                    errors.append(np.abs(state.q - predict.qpos[qpos]).max())
                    naive.append(np.abs(state.q - last.q - last.dq * steps / 1000).max())
                last = state
        panda.stop_controller()

        site = mirror.site("flange").xpos
        print(f"mirrored {ctx.num_ticks} states; the scene's flange is at {np.round(site, 3)} m")
        print(f"MuJoCo's prediction, one step ahead: mean error {np.mean(errors) * 1000:.3f} "
              f"mrad (constant velocity: {np.mean(naive) * 1000:.3f} mrad)")  # fmt: skip
        panda.close()

    if frames:
        import matplotlib.pyplot as plt

        plt.imsave(args.record, np.concatenate(frames, axis=1))
        print(f"recorded {len(frames)} frames: {args.record}")
