"""Per-user storage of control tokens and pinned certificate fingerprints.

One JSON file (mode 0600) in a directory of its own (mode 0700), written atomically
(temporary file, then rename) so that a crash never leaves half a file:

    {"hosts": {"<host[:port]>": {"fingerprint": "sha256 hex",
                                 "tokens": {"<user>": {"id": ..., "token": ..., "owned_by": ...}}}}}
"""

from __future__ import annotations

import json
import logging
import os
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

log = logging.getLogger("panda_py.desk")

FILE_NAME = "desk.json"


def default_directory() -> Path:
    """``$PANDA_PY_DESK_DIR``, else ``$XDG_STATE_HOME/panda_py/desk`` (``~/.local/state``)."""
    env = os.environ.get("PANDA_PY_DESK_DIR")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_STATE_HOME") or os.path.expanduser("~/.local/state")
    return Path(base) / "panda_py" / "desk"


#: panda-py's name: the file holding control tokens (and here the pinned certificates),
#: as resolved at import; ``Desk(token_dir=...)`` or ``$PANDA_PY_DESK_DIR`` choose another.
TOKEN_PATH = str(default_directory() / FILE_NAME)


@dataclass(frozen=True)
class Token:
    """A control token: ``id`` (as text), the owner's name and the secret itself.
    The secret never appears in ``repr``."""

    id: str = ""
    owned_by: str = ""
    token: str = ""

    def __repr__(self) -> str:
        return f"Token(id={self.id!r}, owned_by={self.owned_by!r}, token=<hidden>)"

    def __bool__(self) -> bool:
        return bool(self.token)


class TokenStore:
    """Tokens and certificate fingerprints for every robot this user talked to."""

    def __init__(self, directory: str | os.PathLike[str] | None = None) -> None:
        self.directory = Path(directory) if directory is not None else default_directory()
        self.path = self.directory / FILE_NAME

    def _load(self) -> dict[str, Any]:
        try:
            with open(self.path, encoding="utf-8") as f:
                data = json.load(f)
        except FileNotFoundError:
            return {"hosts": {}}
        except (OSError, ValueError) as exc:
            log.warning("ignoring unreadable Desk store %s: %s", self.path, exc)
            return {"hosts": {}}
        if not isinstance(data, dict) or not isinstance(data.get("hosts"), dict):
            return {"hosts": {}}
        return data

    def _save(self, data: dict[str, Any]) -> None:
        self.directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        mode = stat.S_IMODE(self.directory.stat().st_mode)
        if mode & 0o077:
            os.chmod(self.directory, 0o700)
        fd, tmp = tempfile.mkstemp(prefix=".desk.", suffix=".tmp", dir=self.directory)
        try:
            os.fchmod(fd, 0o600)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(data, f, indent=1, sort_keys=True)
            os.replace(tmp, self.path)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise

    def _host(self, data: dict[str, Any], host: str) -> dict[str, Any]:
        entry = data["hosts"].setdefault(host, {})
        entry.setdefault("tokens", {})
        return entry

    # -- certificates --------------------------------------------------------------------

    def fingerprint(self, host: str) -> str | None:
        """The certificate fingerprint pinned for ``host`` (SHA-256, colon-separated hex),
        or None before the first connection."""
        value = self._load()["hosts"].get(host, {}).get("fingerprint")
        return value if isinstance(value, str) else None

    def pin(self, host: str, fingerprint: str) -> None:
        """Pin ``fingerprint`` as ``host``'s certificate (written at once, file mode 0600)."""
        data = self._load()
        self._host(data, host)["fingerprint"] = fingerprint
        self._save(data)

    # -- tokens --------------------------------------------------------------------------

    def token(self, host: str, user: str) -> Token:
        """The control token saved for ``user`` on ``host`` (an empty, false :class:`Token` if
        none)."""
        raw = self._load()["hosts"].get(host, {}).get("tokens", {}).get(user)
        if not isinstance(raw, dict):
            return Token()
        try:
            return Token(str(raw["id"]), str(raw["owned_by"]), str(raw["token"]))
        except KeyError:
            return Token()

    def save_token(self, host: str, user: str, token: Token) -> None:
        """Save ``user``'s control token for ``host``; an empty token removes it."""
        data = self._load()
        tokens = self._host(data, host)["tokens"]
        if token:
            tokens[user] = {"id": token.id, "owned_by": token.owned_by, "token": token.token}
        else:
            tokens.pop(user, None)
        self._save(data)


__all__ = ["TOKEN_PATH", "Token", "TokenStore", "default_directory"]
