"""The Desk client: log into a Franka's web Desk, take control, unlock, activate the FCI,
and the Desk's other duties (shutdown, end-effector configuration, pack pose, self-test,
recoveries, and a bring-up that does all a robot needs before control).

Speaks the legacy web API and Desk API v1; pins the robot's certificate on first use.
"""

from panda_py.desk.api import DeskAPI, encode_password
from panda_py.desk.client import Desk
from panda_py.desk.duties import BringUpReport
from panda_py.desk.end_effector import PAYLOAD_MAX, EndEffectorConfig, check_payload
from panda_py.desk.errors import (
    BrakesError,
    BringUpError,
    BringUpStep,
    CertificateChangedError,
    ControlNotGrantedError,
    DeskAnswerError,
    DeskConnectionError,
    DeskError,
    DeskHTTPError,
    DeskTimeoutError,
    DeskUnsupportedError,
    FCIRefusedError,
    NotInControlError,
    OperatingModeError,
    RecoveryRefusedError,
    SelfTestFailedError,
    TakeControlTimeoutError,
)
from panda_py.desk.store import TOKEN_PATH, Token, TokenStore
from panda_py.desk.transport import MockTransport, Request, Response

__all__ = [
    "PAYLOAD_MAX",
    "TOKEN_PATH",
    "BrakesError",
    "BringUpError",
    "BringUpReport",
    "BringUpStep",
    "CertificateChangedError",
    "ControlNotGrantedError",
    "Desk",
    "DeskAPI",
    "DeskAnswerError",
    "DeskConnectionError",
    "DeskError",
    "DeskHTTPError",
    "DeskTimeoutError",
    "DeskUnsupportedError",
    "EndEffectorConfig",
    "FCIRefusedError",
    "MockTransport",
    "NotInControlError",
    "OperatingModeError",
    "RecoveryRefusedError",
    "Request",
    "Response",
    "SelfTestFailedError",
    "TakeControlTimeoutError",
    "Token",
    "TokenStore",
    "check_payload",
    "encode_password",
]
