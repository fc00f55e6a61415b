"""Reading a Desk's answers: the values expected, or a
:class:`~panda_py.desk.errors.DeskAnswerError` naming the request, the status, what was
expected and what came (one line, credentials hidden).

A parse function given to :func:`parse` indexes and converts freely (``body["tokenId"]``,
``text(...)``); what a malformed answer makes it raise (``KeyError``, ``TypeError``,
``ValueError``, ...) becomes the error here, in one place (``shapes.py`` has the checks
that indexing does not make).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

from panda_py.desk.errors import DeskAnswerError
from panda_py.desk.excerpt import excerpt, redact, request_secrets
from panda_py.desk.transport import Response

T = TypeVar("T")
# what reading a JSON document of another shape raises (RecursionError: nested too deep)
SHAPE_ERRORS = (KeyError, IndexError, TypeError, ValueError, AttributeError, RecursionError)
_COOKIE_VALUE = re.compile(r"[!#-+\--:<-\[\]-~]+")  # RFC 6265's cookie-octets


def answer_error(
    response: Response, problem: str, secrets: Iterable[str] = (), *, show: bool = True
) -> DeskAnswerError:
    """The error for ``response`` (whose ``request`` the client set): ``problem`` says
    what is wrong; the body's beginning is shown if ``show``."""
    request = response.request
    method, path = (request.method, request.path) if request else ("?", "?")
    hidden = [*secrets, *(request_secrets(request.headers, request.body) if request else ())]
    shown = excerpt(response.body, hidden) if show else ""
    return DeskAnswerError(method, path, response.status, redact(problem, hidden), shown)


def json_body(response: Response, secrets: Iterable[str] = ()) -> Any:
    """The JSON document of ``response`` (None for an empty body)."""
    if not response.body:
        return None
    try:
        return json.loads(response.body)
    except ValueError as exc:
        raise answer_error(response, "no JSON where JSON was due", secrets) from exc
    except RecursionError as exc:
        raise answer_error(response, "JSON nested deeper than Python's stack", secrets) from exc


def _identity(body: Any) -> Any:
    return body


def parse(
    response: Response,
    expected: str = "JSON",
    read: Callable[[Any], T] = _identity,
    secrets: Iterable[str] = (),
) -> T:
    """``read`` applied to the JSON document of ``response``; ``expected`` describes the
    shape it needs, for the error if it is another."""
    secrets = list(secrets)
    body = json_body(response, secrets)
    try:
        return read(body)
    except SHAPE_ERRORS as exc:
        why = f"no {exc.args[0]!r}" if isinstance(exc, KeyError) else f"{exc}"
        problem = f"JSON of another shape (expected {expected}; {why})"
        raise answer_error(response, problem, secrets) from exc


def session_of(response: Response, secrets: Iterable[str] = ()) -> str:
    """The legacy login's session token (the answer's text), which goes back as a
    cookie: RFC 6265's cookie characters only. Its text is not shown in the error
    (it is the credential)."""
    try:
        session = response.body.decode("ascii").strip()
    except UnicodeDecodeError:
        session = None
    if session is None or not _COOKIE_VALUE.fullmatch(session):
        what = "not ASCII text" if session is None else "not only cookie characters"
        problem = f"a session of {len(response.body)} bytes, {what}, which no cookie can carry"
        raise answer_error(response, problem, secrets, show=False)
    return session


__all__ = ["SHAPE_ERRORS", "answer_error", "json_body", "parse", "session_of"]
