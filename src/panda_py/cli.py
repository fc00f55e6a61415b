"""panda-py's console scripts: ``panda-unlock`` (unlock the brakes, activate the FCI),
``panda-lock``, ``panda-reboot``, ``panda-take-control``, ``panda-release-control``.

Arguments as panda-py's: ``host user [password] [--platform]``. Leave the password out:
it is then read from ``PANDA_PY_PASSWORD`` or prompted for, so it never shows in the
process list (a password given as an argument still works, with a warning).

Whatever the robot answers, and whatever the arguments, a failure is one line on stderr
(``prog: what happened``) and a non-zero exit status: 1 for a failure, 2 for bad
arguments, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import getpass
import logging
import os
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

from panda_py import checks
from panda_py.desk import Desk, DeskError
from panda_py.desk.excerpt import one_line

PASSWORD_ENV = "PANDA_PY_PASSWORD"


class _Parser(argparse.ArgumentParser):
    """argparse's parser, its errors on one line (argparse prints the usage first)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message, 500)} (see {self.prog} --help)\n")


def _seconds(text: str) -> float:
    """``--timeout``'s value: a number of seconds that every socket accepts."""
    try:
        return checks.timeout("--timeout", float(text))
    except ValueError as exc:
        # (argparse names the option itself)
        raise argparse.ArgumentTypeError(
            f"expected a number of seconds [s] in (0, {checks.MAX_TIMEOUT:g}], got {text!r}"
        ) from exc


def _parser(prog: str, description: str, *, platform: bool) -> argparse.ArgumentParser:
    p = _Parser(prog=prog, description=description)
    p.add_argument("host", help="the robot's Desk address (host or host:port)")
    p.add_argument("user", help="Desk user name")
    p.add_argument(
        "password",
        nargs="?",
        help=f"Desk password; better omitted: then ${PASSWORD_ENV} or a prompt",
    )
    if platform:
        p.add_argument("--platform", default=None, help="panda (fer) or fr3; detected if omitted")
    p.add_argument(
        "--timeout",
        type=_seconds,
        default=10.0,
        help="seconds each request may take, all of it (default %(default)g)",
    )
    p.add_argument(
        "--repin",
        action="store_true",
        help="accept and pin the robot's certificate although it differs from the pinned one",
    )
    return p


def _password(args: argparse.Namespace, prog: str) -> str | None:
    if args.password is not None:
        print(
            f"{prog}: warning: a password on the command line is visible to every user of "
            f"this machine; omit it and set ${PASSWORD_ENV} or type it at the prompt",
            file=sys.stderr,
        )
        return str(args.password)
    env = os.environ.get(PASSWORD_ENV)
    if env:
        return env
    if sys.stdin is not None and sys.stdin.isatty():
        return getpass.getpass(f"Desk password for {args.user}@{args.host}: ")
    print(f"{prog}: no password: set ${PASSWORD_ENV} or run interactively", file=sys.stderr)
    return None


def _run(
    prog: str,
    description: str,
    action: Callable[[Desk, argparse.Namespace], int],
    argv: Sequence[str] | None,
    *,
    platform: bool = True,
    extra: Callable[[argparse.ArgumentParser], None] | None = None,
) -> int:
    parser = _parser(prog, description, platform=platform)
    if extra is not None:
        extra(parser)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format=f"{prog}: %(message)s")
    password = _password(args, prog)
    if password is None:
        return 2
    try:
        desk = Desk(
            args.host,
            args.user,
            password,
            platform=getattr(args, "platform", None),
            timeout=args.timeout,
            repin=args.repin,
        )
        return action(desk, args)
    except (DeskError, ValueError, OSError) as exc:  # OSError: the token store's file
        print(f"{prog}: {one_line(str(exc), 1000)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


def _in_control(desk: Desk, prog: str) -> bool:
    if desk.has_control():
        return True
    print(f"{prog}: another user is in control; try panda-take-control --force", file=sys.stderr)
    return False


def unlock(argv: Sequence[str] | None = None) -> int:
    """Unlock the brakes and activate the FCI."""

    def act(desk: Desk, args: argparse.Namespace) -> int:
        if not _in_control(desk, "panda-unlock"):
            return 1
        desk.unlock()
        desk.activate_fci()
        return 0

    return _run("panda-unlock", "Unlock the brakes and activate the FCI.", act, argv)


def lock(argv: Sequence[str] | None = None) -> int:
    """Deactivate the FCI and lock the brakes."""

    def act(desk: Desk, args: argparse.Namespace) -> int:
        if not _in_control(desk, "panda-lock"):
            return 1
        desk.deactivate_fci()
        desk.lock()
        return 0

    return _run("panda-lock", "Deactivate the FCI and lock the brakes.", act, argv)


def reboot(argv: Sequence[str] | None = None) -> int:
    """Reboot the robot's control unit."""

    def act(desk: Desk, args: argparse.Namespace) -> int:
        if not _in_control(desk, "panda-reboot"):
            return 1
        desk.reboot()
        return 0

    return _run("panda-reboot", "Reboot the robot.", act, argv, platform=False)


def take_control(argv: Sequence[str] | None = None) -> int:
    """Take control of the Desk (``--force``: confirm on the robot's Pilot)."""

    def add(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--force",
            action="store_true",
            help="take control from another user, confirmed by pressing the Pilot's circle "
            "(FER) or top (FR3) button",
        )

    def act(desk: Desk, args: argparse.Namespace) -> int:
        if desk.has_control() or desk.take_control(force=args.force):
            return 0
        print("panda-take-control: another user is in control (use --force)", file=sys.stderr)
        return 1

    return _run(
        "panda-take-control", "Take control of the Desk.", act, argv, platform=False, extra=add
    )


def release_control(argv: Sequence[str] | None = None) -> int:
    """Release control of the Desk."""

    def act(desk: Desk, args: argparse.Namespace) -> int:
        if not desk.has_control():
            print("panda-release-control: this user is not in control", file=sys.stderr)
            return 1
        desk.release_control()
        return 0

    return _run("panda-release-control", "Release control of the Desk.", act, argv, platform=False)


__all__ = ["lock", "reboot", "release_control", "take_control", "unlock"]
