"""Unlock the brakes and activate FCI through Desk, then connect (the paper's code block 1).

The password comes from ``--password``, ``PANDA_PY_PASSWORD`` or a prompt; the simulated
robot's Desk accepts franka / franka123."""

import getpass
import os
import sys

import numpy as np
from _robot import connect, robot_host

import panda_py
from panda_py.desk import DeskError, DeskHTTPError


def options(parser):
    parser.add_argument("--user", default="franka", help="the Desk user")
    parser.add_argument("--password", help="the Desk password (default: PANDA_PY_PASSWORD)")


if __name__ == "__main__":
    with robot_host(__doc__, options=options, desk=True) as (hostname, args):
        password = args.password or os.environ.get("PANDA_PY_PASSWORD")
        if password is None:
            password = "franka123" if args.host is None else getpass.getpass("Desk password: ")
        try:
            desk = panda_py.Desk(args.desk_host, args.user, password)  # logs in, takes control
            desk.unlock()  # opens the brakes
            desk.activate_fci()
        except DeskHTTPError as exc:
            if exc.status in (401, 403):
                sys.exit(f"Desk at {args.desk_host} refused {args.user!r}: wrong password?")
            sys.exit(f"Desk at {args.desk_host}: {exc}")
        except DeskError as exc:
            sys.exit(f"No Desk answers at {args.desk_host} ({exc})")
        print("brakes open, FCI active")

        panda = connect(hostname)
        panda.move_to_start()
        print("at the start pose:", np.round(panda.q, 3) + 0.0)  # + 0.0: no "-0."
        panda.close()
        desk.lock()  # closes the brakes again
        desk.release_control()
        print("brakes locked, control released")
