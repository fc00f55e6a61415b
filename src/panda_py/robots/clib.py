"""The native model library the simulated robot serves on LoadModelLibrary (protocol v4..v9).

libfranka 0.9.x asks the robot for a shared library built for the client's own platform,
``dlopen``s the bytes and resolves 30 plain-C functions (fci-protocol.md §12.1). We
generate that library's C source from the parameter tables
(:func:`panda_py.robots.csource.c_source`) and compile it with the local C compiler on
first use. The result is cached on disk under ``$PANDA_PY_CACHE/models/<key>/`` (default
``~/.cache/panda_py/models/<key>/``), where ``key`` is the SHA-256 of the source, the
compiler's identity, the flags and the platform, and written atomically (temporary file,
then rename), so parallel processes can share the cache safely.

Only the host's own architecture and system can be built. Anything else, a missing
compiler or a failed build raises :class:`ModelLibraryUnavailable`; the simulator answers
the request with kError then, which libfranka reports as "Server reports error when
loading model library" (plain ``Robot`` use still works without a model).
"""

from __future__ import annotations

import hashlib
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from panda_py import progress
from panda_py.fci.enums import ModelLibraryArchitecture, ModelLibrarySystem
from panda_py.robots.csource import EXPORTED_SYMBOLS, c_source
from panda_py.robots.params import RobotSpec, get_robot

__all__ = [
    "EXPORTED_SYMBOLS",
    "Architecture",
    "ModelLibraryUnavailable",
    "System",
    "c_source",
    "host_platform",
    "model_library",
]


# The protocol's platform enums live with the protocol (re-exported here).
Architecture = ModelLibraryArchitecture
System = ModelLibrarySystem


# ELF e_machine of each architecture (System V ABI), to check what the compiler built.
_ELF_MACHINE = {
    Architecture.X64: 62,
    Architecture.X86: 3,
    Architecture.ARM: 40,
    Architecture.ARM64: 183,
}

_CFLAGS = ("-std=c99", "-O2", "-shared", "-fPIC")
_LIBS = ("-lm",)
_COMPILE_TIMEOUT = 120.0  # [s]

_lock = threading.Lock()
_memory: dict[str, bytes] = {}  # cache key -> library bytes (this process)
_compiler_ids: dict[tuple[str, ...], str] = {}


class ModelLibraryUnavailable(RuntimeError):
    """The model library for the requested platform cannot be produced here.

    ``architecture`` and ``system`` are what was asked for (ints as on the wire, or the
    enum members when known); ``reason`` says why it cannot be built."""

    def __init__(self, architecture: int, system: int, reason: str) -> None:
        self.architecture = architecture
        self.system = system
        self.reason = reason
        super().__init__(
            f"cannot build the model library for {_describe(architecture, system)}: {reason}"
        )


def _describe(architecture: int, system: int) -> str:
    try:
        arch = Architecture(architecture).name
    except ValueError:
        arch = f"unknown architecture {architecture}"
    try:
        sysname = System(system).name
    except ValueError:
        sysname = f"unknown system {system}"
    return f"{arch}/{sysname}"


def host_platform() -> tuple[Architecture, System] | None:
    """This machine's (architecture, system) in LoadModelLibrary's terms, or None if the
    protocol has no name for it."""
    machine = platform.machine().lower()
    bits64 = sys.maxsize > 2**32
    arch: Architecture | None
    if machine in ("x86_64", "amd64", "i386", "i686", "x86"):
        arch = Architecture.X64 if bits64 else Architecture.X86
    elif machine in ("aarch64", "arm64") or machine.startswith("arm"):
        arch = Architecture.ARM64 if bits64 else Architecture.ARM
    else:
        arch = None
    if sys.platform.startswith("linux"):
        system: System | None = System.LINUX
    elif sys.platform in ("win32", "cygwin"):
        system = System.WINDOWS
    else:
        system = None
    if arch is None or system is None:
        return None
    return arch, system


def _compiler(architecture: int, system: int) -> list[str]:
    """The C compiler command: $CC (may carry arguments), else cc or gcc on PATH."""
    env = os.environ.get("CC", "").strip()
    if env:
        cmd = shlex.split(env)
        path = shutil.which(cmd[0])
        if path is None:
            raise ModelLibraryUnavailable(
                architecture, system, f"the C compiler $CC={env!r} was not found"
            )
        return [path, *cmd[1:]]
    for name in ("cc", "gcc"):
        path = shutil.which(name)
        if path is not None:
            return [path]
    raise ModelLibraryUnavailable(
        architecture, system, "no C compiler found (set $CC or install cc/gcc)"
    )


def _compiler_identity(cmd: list[str], architecture: int, system: int) -> str:
    key = tuple(cmd)
    ident = _compiler_ids.get(key)
    if ident is None:
        try:
            proc = subprocess.run(
                [*cmd, "--version"], capture_output=True, text=True, timeout=30.0, check=False
            )
        except (OSError, subprocess.SubprocessError) as exc:
            raise ModelLibraryUnavailable(
                architecture, system, f"the C compiler {cmd[0]} cannot be run: {exc}"
            ) from exc
        ident = " ".join(cmd) + "\n" + proc.stdout + proc.stderr
        _compiler_ids[key] = ident
    return ident


def _cache_root() -> Path:
    root = os.environ.get("PANDA_PY_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "panda_py"
    return base / "models"


def _check_elf(data: bytes, architecture: Architecture) -> str | None:
    if data[:4] != b"\x7fELF" or len(data) < 20:
        return "the compiler did not produce an ELF shared object"
    little = data[5] == 1
    machine = int.from_bytes(data[18:20], "little" if little else "big")
    if machine != _ELF_MACHINE[architecture]:
        return f"the compiler built for ELF machine {machine}, not {architecture.name}"
    return None


def _build(cmd: list[str], source: str, target: Path, architecture: Architecture) -> bytes:
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".build-") as tmp:
        src = Path(tmp) / "model.c"
        out = Path(tmp) / target.name
        src.write_text(source)
        try:
            proc = subprocess.run(
                [*cmd, *_CFLAGS, "-o", str(out), str(src), *_LIBS],
                capture_output=True,
                text=True,
                timeout=_COMPILE_TIMEOUT,
                check=False,
            )
        except (OSError, subprocess.SubprocessError) as exc:
            raise ModelLibraryUnavailable(
                architecture, System.LINUX, f"running {cmd[0]} failed: {exc}"
            ) from exc
        if proc.returncode != 0 or not out.exists():
            detail = (proc.stderr or proc.stdout).strip()[-2000:]
            raise ModelLibraryUnavailable(
                architecture,
                System.LINUX,
                f"{cmd[0]} failed with exit status {proc.returncode}: {detail}",
            )
        data = out.read_bytes()
        problem = _check_elf(data, architecture)
        if problem is not None:
            raise ModelLibraryUnavailable(architecture, System.LINUX, problem)
        os.replace(out, target)  # atomic: readers see the old state or the whole file
    return data


def model_library(
    robot: str | RobotSpec = "fer",
    *,
    architecture: int = Architecture.X64,
    system: int = System.LINUX,
) -> bytes:
    """The bytes of the model library (a shared object exporting the 30 functions of
    :data:`EXPORTED_SYMBOLS`) for ``robot`` on the requested platform (LoadModelLibrary's
    ``architecture``/``system`` values, default x86-64 Linux).

    Compiles on first use (the compiler from ``$CC``, else ``cc``/``gcc``) and caches the
    result on disk and in memory. Raises :class:`ModelLibraryUnavailable` when the
    platform is not this host's, there is no compiler, or the build fails; ``ValueError``
    for an unknown robot or non-integer platform values.
    """
    spec = get_robot(robot)
    for name, value in (("architecture", architecture), ("system", system)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{name}: expected an integer enum value, got {value!r}")
    host = host_platform()
    if host is None:
        raise ModelLibraryUnavailable(
            architecture,
            system,
            f"this host ({platform.machine()}, {sys.platform}) has no LoadModelLibrary platform",
        )
    if (architecture, system) != (int(host[0]), int(host[1])):
        raise ModelLibraryUnavailable(
            architecture,
            system,
            f"only this host's platform {_describe(*host)} can be compiled here",
        )
    if host[1] is not System.LINUX:
        raise ModelLibraryUnavailable(
            architecture, system, "only Linux shared objects can be built"
        )
    arch = host[0]
    cmd = _compiler(architecture, system)
    source = c_source(spec)
    digest = hashlib.sha256()
    for part in (source, _compiler_identity(cmd, architecture, system), *_CFLAGS, *_LIBS):
        digest.update(part.encode())
        digest.update(b"\0")
    digest.update(f"{arch.name}/{System.LINUX.name}".encode())
    key = digest.hexdigest()
    with _lock:
        data = _memory.get(key)
        if data is not None:
            return data
        target = _cache_root() / key / f"libpanda_model_{spec.name}.so"
        try:
            data = target.read_bytes()
        except OSError:
            data = None
        if data is None or _check_elf(data, arch) is not None:
            what = f"panda_py: building the {spec.name.upper()} model library, once"
            try:
                with progress.work(what):
                    data = _build(cmd, source, target, arch)
            except OSError as exc:
                raise ModelLibraryUnavailable(
                    architecture, system, f"cannot write the cache under {target.parent}: {exc}"
                ) from exc
        _memory[key] = data
        return data
