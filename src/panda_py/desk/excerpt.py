"""What of a Desk's answer may go into an error: one printable line, short, and never a
credential.

An answer can echo the request: an error page showing the request's head, a form showing
its fields, and with them the ``Authorization`` header (v1's user and password, base64),
the session cookie, the control token, the legacy login's password hash. An exception's
text is logged, printed by the console scripts and pickled to other processes, so every
text taken from an answer passes :func:`redact` first: the secrets the client knows it
sent are replaced wherever they appear, then whatever looks like a credential by its name
(``Authorization: ...``, ``"password": "..."``, ``token=...``).
"""

from __future__ import annotations

import base64
import binascii
import json
import re
from collections.abc import Iterable, Mapping

HIDDEN = "<hidden>"
EXCERPT = 200  # [characters] of an answer shown in an error
# [characters] the shortest secret replaced wherever it appears: a shorter one (a
# 1-character password) would garble every word that holds it, and hides little.
SHORTEST_SECRET = 4

# A credential by its name: the name, a closing quote, ':' or '=', then a quoted value or
# a bare one (with its scheme, as in "Basic dXNlcjpw..."). "tokenId" or "activeToken" are
# no such names (\b), so ids and owners stay readable.
_NAMES = r"(?:proxy-)?authorization|set-cookie|cookie|x-control-token|token|password|passwd|secret"
_CREDENTIAL = re.compile(
    rf"""(?P<name>\b(?:{_NAMES})\b["']?\s*[:=]\s*)"""
    r"""(?:(?P<q>["'])(?:\\.|(?!(?P=q)).)*(?P=q)"""
    r"""|(?:(?:basic|bearer|digest|negotiate)[ \t]+)?[^\s,;&"'}\]]+)""",
    re.IGNORECASE,
)
_SECRET_HEADERS = ("authorization", "cookie", "x-control-token", "proxy-authorization")
_SECRET_FIELDS = ("password", "token")


def _hide_by_name(match: re.Match[str]) -> str:
    quote = match.group("q") or ""
    return f"{match.group('name')}{quote}{HIDDEN}{quote}"


def redact(text: str, secrets: Iterable[str] = ()) -> str:
    """``text`` with each of ``secrets`` (also JSON-escaped; those of at least
    :data:`SHORTEST_SECRET` characters) and every credential by its name replaced by
    ``<hidden>``."""
    variants = set()
    for secret in secrets:
        if len(secret) >= SHORTEST_SECRET:
            variants.add(secret)
            variants.add(json.dumps(secret)[1:-1])
    for secret in sorted(variants, key=len, reverse=True):  # a secret's parts after it
        text = text.replace(secret, HIDDEN)
    return _CREDENTIAL.sub(_hide_by_name, text)


def one_line(text: str, limit: int = EXCERPT) -> str:
    """``text`` stripped, its first ``limit`` characters on one line: line breaks and other
    unprintable characters escaped as a Python literal shows them, '...' where cut."""
    text = text.strip()
    cut = len(text) > limit
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text[:limit])
    return shown[:limit] + ("..." if cut or len(shown) > limit else "")


def excerpt(data: bytes | str, secrets: Iterable[str] = (), *, limit: int = EXCERPT) -> str:
    """The beginning of ``data`` (an answer's body) as one line of at most ``limit``
    characters, credentials hidden; bytes that are not UTF-8 shown as ``\\xNN``, and said
    to be binary."""
    if isinstance(data, str):
        return one_line(redact(data, secrets), limit)
    try:
        return one_line(redact(data.decode("utf-8"), secrets), limit)
    except UnicodeDecodeError:
        text = data.decode("utf-8", "backslashreplace")
        return f"{len(data)} bytes, not UTF-8 text: {one_line(redact(text, secrets), limit)}"


def request_secrets(headers: Mapping[str, str], body: bytes | None = None) -> list[str]:
    """The credentials a request carries: its authorization, cookie and control-token
    headers (whole, without their scheme, and Basic's user:password decoded), and the
    ``password`` and ``token`` fields of a JSON body."""
    found: list[str] = []
    for name, value in headers.items():
        if name.lower() not in _SECRET_HEADERS:
            continue
        found.append(value)
        scheme, _, credential = value.partition(" ")
        if credential:
            found.append(credential)
            if scheme.lower() == "basic":
                try:
                    decoded = base64.b64decode(credential, validate=True).decode()
                except (binascii.Error, UnicodeDecodeError):
                    continue
                found += [decoded, decoded.partition(":")[2]]
        found += [part.partition("=")[2] for part in value.split(";") if "=" in part]
    if body:
        try:
            document = json.loads(body)
        except ValueError:
            document = None
        if isinstance(document, dict):
            found += [str(document[k]) for k in _SECRET_FIELDS if document.get(k)]
    return [secret for secret in found if secret.strip()]


__all__ = [
    "EXCERPT",
    "HIDDEN",
    "SHORTEST_SECRET",
    "excerpt",
    "one_line",
    "redact",
    "request_secrets",
]
