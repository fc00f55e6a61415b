"""Line protocol between a peer script (run inside a peer's venv) and the test process.

Kept free of third-party imports: it runs under any peer's interpreter.
"""

from __future__ import annotations

import json
import sys
import traceback
from collections.abc import Callable
from typing import Any


def event(name: str, arg: Any = None) -> Any:
    """Tell the test ``name`` happened and wait for its JSON answer."""
    print(f"EVENT {name} {json.dumps(arg)}", flush=True)
    line = sys.stdin.readline()
    if not line:
        raise RuntimeError(f"the test closed the pipe while answering {name}")
    return json.loads(line)


def log(*parts: Any) -> None:
    print(*parts, flush=True)


class Scenarios:
    """Runs named scenarios in order, recording each outcome (or its exception)."""

    def __init__(self) -> None:
        self.results: dict[str, Any] = {}

    def run(self, name: str, fn: Callable[[], dict[str, Any]]) -> None:
        try:
            self.results[name] = fn()
        except Exception as exc:  # reported to the test, not hidden
            self.results[name] = {
                "scenario_error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(),
            }
        log(f"scenario {name} done")

    def finish(self) -> None:
        print("RESULT " + json.dumps(self.results), flush=True)


def floats(x: Any) -> list[float]:
    return [float(v) for v in x]
