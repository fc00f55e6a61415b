"""The Desk client: log into a Franka's web Desk, take control, unlock, activate the FCI.

Speaks the legacy web API and Desk API v1; pins the robot's certificate on first use.
"""

from panda_py.desk.api import encode_password
from panda_py.desk.client import Desk, DeskAPI
from panda_py.desk.errors import (
    CertificateChangedError,
    DeskConnectionError,
    DeskError,
    DeskHTTPError,
    NotInControlError,
    TakeControlTimeoutError,
)
from panda_py.desk.store import TOKEN_PATH, Token, TokenStore
from panda_py.desk.transport import MockTransport, Request, Response

__all__ = [
    "TOKEN_PATH",
    "CertificateChangedError",
    "Desk",
    "DeskAPI",
    "DeskConnectionError",
    "DeskError",
    "DeskHTTPError",
    "MockTransport",
    "NotInControlError",
    "Request",
    "Response",
    "TakeControlTimeoutError",
    "Token",
    "TokenStore",
    "encode_password",
]
