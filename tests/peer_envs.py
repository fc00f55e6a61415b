"""Virtual environments holding real, unmodified Franka clients (test oracles only).

Each peer lives in its own venv under ``$PANDA_PY_PEER_CACHE`` (default
``~/.cache/panda-py-peers``), created on first use and reused afterwards. The package never
imports any of them; tests and benchmarks run them as separate processes.
"""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
from pathlib import Path

PEERS: dict[str, list[str]] = {
    "panda-python": ["panda-python==1.1.1"],  # libfranka 0.9.2, protocol 5
    "pylibfranka": ["pylibfranka==0.21.3"],  # libfranka 0.21.3, protocol 10
    "franky": ["franky-control==2.0.0"],  # libfranka 0.21.2, protocol 10
    "franky-sim": ["franky-sim==1.0.4"],  # the reference protocol-level simulator
    # Rust 1 kHz loop behind Python bindings: benchmarks/peer_franka_rs.py
    "franka-rs": ["franka-rs==0.4.0"],
    # panda-gym's PyBullet PandaReach-v3: benchmarks/bench_learning.py's peer
    "panda-gym": ["panda-gym==3.0.7", "pybullet==3.2.7"],
    # the analytical ik with a q7 search: benchmarks/bench_kinematics.py --search's peer
    "frankik": ["frankik==1.0.1"],
    # LeRobot's own dataset loader: tests/learning/test_lerobot.py reads our episodes with it.
    # 0.4.4 is the newest on Python 3.10-3.11 (0.5+ need 3.12); it reads and writes the
    # same dataset format as 0.6 (codebase v3.0). torch pinned to a pair whose torchvision
    # still decodes video with PyAV; PyPI's x86_64 torch is a CUDA build: 4-5 GB on disk.
    "lerobot": ["lerobot==0.4.4", "torch==2.9.1", "torchvision==0.24.1", "torchcodec==0.8.1"],
    # openpi's own policy client (examples/21_openpi_client.py), which pins numpy<2 (and
    # imports typing_extensions without requiring it), beside this package's runtime
    # dependencies at this environment's versions but numpy 1.x: the example imports this
    # checkout's panda_py there (openpi_environ)
    "openpi-client": [
        "openpi-client==0.1.2",
        "typing-extensions==4.15.0",
        *("numpy==1.26.4", "ruckig==0.19.4", "mujoco==4.0.0", "numba==0.68.1"),
        *("websockets==17.4", "uvicorn==0.54.0", "cryptography==48.0.0"),
        *("matplotlib==3.11.2", "tqdm==4.70.1"),
    ],
}
# this checkout's package, for the peers that run it (openpi_environ)
SRC = Path(__file__).resolve().parents[1] / "src"


class PeerUnavailable(RuntimeError):
    """The peer's virtual environment could not be created (e.g. no package index)."""


def cache_dir() -> Path:
    root = os.environ.get("PANDA_PY_PEER_CACHE") or Path.home() / ".cache" / "panda-py-peers"
    return Path(root)


def peer_python(name: str) -> Path:
    """The interpreter of the venv holding peer ``name``, created (once) if needed."""
    if name not in PEERS:
        raise ValueError(f"name: expected one of {sorted(PEERS)}, got {name!r}")
    tag = f"{name}-py{sys.version_info.major}{sys.version_info.minor}"
    venv = cache_dir() / tag
    python = venv / "bin" / "python"
    marker = venv / ".complete"
    cache_dir().mkdir(parents=True, exist_ok=True)
    with open(cache_dir() / f"{tag}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # several test processes may ask at once
        # a venv made from another recipe (an edited pin) is made again
        if marker.exists() and python.exists() and marker.read_text() == " ".join(PEERS[name]):
            return python
        try:
            subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)], check=True)
            subprocess.run(
                [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
                + PEERS[name],
                check=True,
                timeout=900,
            )
        except (subprocess.CalledProcessError, subprocess.TimeoutExpired, OSError) as exc:
            raise PeerUnavailable(f"could not create the {name} environment: {exc}") from exc
        marker.write_text(" ".join(PEERS[name]))
    return python


def peer_environ() -> dict[str, str]:
    """This process's environment for a peer's interpreter, less PYTHONPATH/PYTHONHOME:
    the peer must import its own ``panda_py``, never this repository's."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}


def openpi_environ() -> dict[str, str]:
    """:func:`peer_environ` for the openpi-client peer, which runs this checkout's
    ``panda_py`` (under its numpy 1.x): PYTHONPATH is this checkout's ``src`` alone."""
    return {**peer_environ(), "PYTHONPATH": str(SRC)}
