"""``panda-sim``'s Desk options and start-up (kept here so the CLI changes by three lines)."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from panda_py.sim.desk.link import DeskLink
from panda_py.sim.desk.process import (
    DEFAULT_PASSWORD,
    DEFAULT_USER,
    DeskConfig,
    DeskProcess,
    DeskStartError,
)

log = logging.getLogger("panda_py.sim")


def add_desk_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group(
        "Desk",
        "the robot's web Desk (HTTPS and WSS on --host, both Desk APIs, a page at "
        f"https://HOST[:PORT]/); default login {DEFAULT_USER} / {DEFAULT_PASSWORD}",
    )
    g.add_argument("--desk-port", type=int, default=443, metavar="PORT", help="default 443")
    g.add_argument("--desk-user", default=DEFAULT_USER, help="default %(default)s")
    g.add_argument("--desk-password", default=DEFAULT_PASSWORD, help="default %(default)s")
    g.add_argument(
        "--desk-cert-dir",
        metavar="DIR",
        help="where the self-signed certificate is generated and kept "
        "(default ~/.cache/panda_py/desk)",
    )
    g.add_argument(
        "--force-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds to press the Pilot after a forced take of control (default 10)",
    )
    state = g.add_mutually_exclusive_group()
    state.add_argument(
        "--ready",
        dest="locked",
        action="store_false",
        help="start unlocked with the FCI active (the default)",
    )
    state.add_argument(
        "--locked",
        dest="locked",
        action="store_true",
        help="start as after power-up: brakes closed, FCI inactive",
    )
    g.add_argument("--no-desk", action="store_true", help="no Desk: always ready (FCI only)")
    p.set_defaults(locked=False)  # --ready's store_false would otherwise default to locked


def start_desk(args: argparse.Namespace, host: str, robot: str) -> tuple[DeskProcess | None, Any]:
    """The running Desk (or None) and the shared block for ``SimConfig.desk_link``.

    A ready robot whose Desk cannot start (port 443 needs privileges) keeps serving the FCI,
    with a warning; a ``--locked`` one cannot be unlocked without it, so that is an error.
    """
    if args.no_desk:
        if args.locked:
            raise ValueError("--locked needs the Desk to unlock the robot (drop --no-desk)")
        return None, None
    config = DeskConfig(
        port=args.desk_port,
        user=args.desk_user,
        password=args.desk_password,
        locked=args.locked,
        token_force_timeout=args.force_timeout,
        cert_dir=args.desk_cert_dir,
    )
    link = DeskLink.create(locked=config.locked)
    try:
        ee = str(getattr(args, "end_effector", "hand"))
        desk = DeskProcess(
            host, robot, config, link, args.log_level.upper(), end_effector=ee
        ).start()
    except DeskStartError as exc:
        if args.locked:
            raise
        log.warning("%s; serving the FCI without a Desk (unlocked, FCI active)", exc)
        return None, None
    log.info(
        "Desk at %s (user %s), certificate SHA-256 %s, %s",
        desk.url, config.user, desk.fingerprint, "locked" if config.locked else "ready",
    )  # fmt: skip
    return desk, link.array
