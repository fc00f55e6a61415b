import ctypes
import math
import os
import shutil
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from panda_py import dynamics
from panda_py.robots import clib
from panda_py.robots.clib import (
    EXPORTED_SYMBOLS,
    Architecture,
    ModelLibraryUnavailable,
    System,
    c_source,
    model_library,
)
from panda_py.robots.params import FER, GRAVITY

_CC = os.environ.get("CC", "").split()
HAVE_CC = bool(shutil.which(_CC[0]) if _CC else (shutil.which("cc") or shutil.which("gcc")))
HOST = clib.host_platform()
needs_cc = pytest.mark.skipif(
    not HAVE_CC or HOST is None or HOST[1] is not System.LINUX,
    reason="no C compiler on PATH (or not a Linux host): the model library cannot be built",
)

TOL_FK = 1e-12  # [m] / rotation entries, against an independent DH product
TOL_FD = 1e-8  # Jacobian against central finite differences
TOL_DYN = 1e-9  # [Nm] / [kg m^2], C against dynamics.py
FD_STEP = 1e-6  # [rad]

_vec = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Compile once into a private cache; returns (ctypes library, path, bytes, seconds)."""
    if not HAVE_CC:
        pytest.skip("no C compiler")
    cache = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PANDA_PY_CACHE", str(cache))
        clib._memory.clear()
        t0 = time.perf_counter()
        data = model_library("fer", architecture=int(HOST[0]), system=int(HOST[1]))
        seconds = time.perf_counter() - t0
    path = cache / "lib_under_test.so"
    path.write_bytes(data)
    lib = ctypes.CDLL(str(path))
    for n in range(1, 9):
        getattr(lib, f"O_T_J{n}").argtypes = [_vec, _vec]
    lib.O_T_J9.argtypes = [_vec, _vec, _vec]
    for prefix in ("O_J_J", "Ji_J_J"):
        getattr(lib, f"{prefix}1").argtypes = [_vec]
        for n in range(2, 9):
            getattr(lib, f"{prefix}{n}").argtypes = [_vec, _vec]
        getattr(lib, f"{prefix}9").argtypes = [_vec, _vec, _vec]
    lib.M_NE.argtypes = [_vec, _vec, ctypes.c_double, _vec, _vec]
    lib.c_NE.argtypes = [_vec, _vec, _vec, ctypes.c_double, _vec, _vec]
    lib.g_NE.argtypes = [_vec, _vec, ctypes.c_double, _vec, _vec]
    print(f"\nmodel library: compiled in {seconds:.3f} s, {len(data)} bytes")
    return lib, path, data, cache


def _pose(lib, n, q, F_T_EE=None):
    out = np.zeros(16)
    if n == 9:
        lib.O_T_J9(np.asarray(q, float), np.asarray(F_T_EE, float).ravel(order="F").copy(), out)
    else:
        getattr(lib, f"O_T_J{n}")(np.asarray(q, float), out)
    return out.reshape(4, 4, order="F")


def _jacobian(lib, prefix, n, q, F_T_EE=None):
    out = np.zeros(42)
    fn = getattr(lib, f"{prefix}{n}")
    if n == 1:
        fn(out)
    elif n == 9:
        fn(np.asarray(q, float), np.asarray(F_T_EE, float).ravel(order="F").copy(), out)
    else:
        fn(np.asarray(q, float), out)
    return out.reshape(6, 7, order="F")


def _dh_frames(q):
    def rx(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])

    def rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    def tr(x, y, z):
        T = np.eye(4)
        T[:3, 3] = (x, y, z)
        return T

    dh, T, out = FER.dh, np.eye(4), []
    for i in range(7):
        T = T @ rx(dh.alpha[i]) @ tr(dh.a[i], 0, 0) @ rz(q[i]) @ tr(0, 0, dh.d[i])
        out.append(T)
    out.append(T @ tr(0, 0, dh.flange_d))
    return out


def _random_transform(rng):
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R *= np.sign(np.linalg.det(R))
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = rng.uniform(-0.2, 0.2, 3)
    return T


@needs_cc
def test_exports_exactly_the_30_symbols(built):
    lib, path, data, _ = built
    assert len(EXPORTED_SYMBOLS) == 30
    for name in EXPORTED_SYMBOLS:
        assert getattr(lib, name) is not None
    assert data[:4] == b"\x7fELF"
    if shutil.which("nm"):
        out = subprocess.run(
            ["nm", "-D", "--defined-only", str(path)], capture_output=True, text=True, check=True
        ).stdout
        exported = {line.split()[-1] for line in out.splitlines() if line.split()[1] in "TtDdBbRr"}
        assert exported - {"_init", "_fini"} == set(EXPORTED_SYMBOLS)
        undefined = subprocess.run(
            ["nm", "-D", "--undefined-only", str(path)], capture_output=True, text=True, check=True
        ).stdout
        libm = {s.split()[-1].split("@")[0] for s in undefined.splitlines()}
        libm -= {"__cxa_finalize", "__gmon_start__", "_ITM_deregisterTMCloneTable"}
        libm -= {"_ITM_registerTMCloneTable", "memcpy"}
        assert libm <= {"sin", "cos", "sincos", "sqrt"}


@needs_cc
def test_poses_equal_dh_product(built):
    lib = built[0]
    rng = np.random.default_rng(21)
    for _ in range(10):
        q = rng.uniform(-math.pi, math.pi, 7)
        F_T_EE = _random_transform(rng)
        frames = _dh_frames(q)
        for n in range(1, 9):
            np.testing.assert_allclose(_pose(lib, n, q), frames[n - 1], rtol=0, atol=TOL_FK)
        np.testing.assert_allclose(
            _pose(lib, 9, q, F_T_EE), frames[7] @ F_T_EE, rtol=0, atol=TOL_FK
        )
    # libfranka's kJoint1 is the DH frame J1, at the top of the base for q = 0
    np.testing.assert_allclose(_pose(lib, 1, np.zeros(7))[:3, 3], [0, 0, FER.dh.d[0]], atol=0)


@needs_cc
def test_zero_jacobians_match_finite_differences(built):
    lib = built[0]
    rng = np.random.default_rng(22)
    for _ in range(3):
        q = rng.uniform(-2.5, 2.5, 7)
        F_T_EE = _random_transform(rng)
        for n in range(1, 10):
            J = _jacobian(lib, "O_J_J", n, q, F_T_EE)
            fd = np.zeros((6, 7))
            for j in range(7):
                dq = np.zeros(7)
                dq[j] = FD_STEP
                Tp, Tm = _pose(lib, n, q + dq, F_T_EE), _pose(lib, n, q - dq, F_T_EE)
                fd[:3, j] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * FD_STEP)
                Rrel = Tp[:3, :3] @ Tm[:3, :3].T  # ~ exp([w] 2h), w in base coordinates
                fd[3:, j] = np.array(
                    [Rrel[2, 1] - Rrel[1, 2], Rrel[0, 2] - Rrel[2, 0], Rrel[1, 0] - Rrel[0, 1]]
                ) / (4 * FD_STEP)
            np.testing.assert_allclose(J, fd, rtol=0, atol=TOL_FD, err_msg=f"O_J_J{n}")
            assert not J[:, min(n, 7) :].any()  # joints past frame n do not move it


@needs_cc
def test_body_jacobians_are_zero_jacobians_in_the_frame(built):
    lib = built[0]
    rng = np.random.default_rng(23)
    q = rng.uniform(-2.5, 2.5, 7)
    F_T_EE = _random_transform(rng)
    for n in range(1, 10):
        R = _pose(lib, n, q, F_T_EE)[:3, :3]
        O_J = _jacobian(lib, "O_J_J", n, q, F_T_EE)
        Ji_J = _jacobian(lib, "Ji_J_J", n, q, F_T_EE)
        np.testing.assert_allclose(Ji_J[:3], R.T @ O_J[:3], rtol=0, atol=1e-14)
        np.testing.assert_allclose(Ji_J[3:], R.T @ O_J[3:], rtol=0, atol=1e-14)
    # frame J1 turns about its own z axis, whatever q is
    expected = np.zeros((6, 7))
    expected[5, 0] = 1.0
    np.testing.assert_array_equal(_jacobian(lib, "O_J_J", 1, None), expected)


@needs_cc
def test_dynamics_match_dynamics_py(built):
    lib = built[0]
    rng = np.random.default_rng(24)
    for _ in range(10):
        q = rng.uniform(-2.5, 2.5, 7)
        dq = rng.uniform(-2.0, 2.0, 7)
        m = float(rng.uniform(0.0, 3.0))
        c = rng.uniform(-0.1, 0.1, 3)
        A = rng.normal(scale=0.01, size=(3, 3))
        I = A @ A.T
        I_col = I.ravel(order="F").copy()
        M, cvec, g = np.zeros(49), np.zeros(7), np.zeros(7)
        lib.M_NE(q, I_col, m, c, M)
        lib.c_NE(q, dq, I_col, m, c, cvec)
        lib.g_NE(q, np.array(GRAVITY), m, c, g)
        load = {"m_load": m, "F_x_Cload": c}
        np.testing.assert_allclose(
            M.reshape(7, 7, order="F"), dynamics.mass_matrix(q, I_load=I, **load), atol=TOL_DYN
        )
        np.testing.assert_allclose(
            cvec, dynamics.coriolis(q, dq, I_load=I, **load), rtol=0, atol=TOL_DYN
        )
        np.testing.assert_allclose(g, dynamics.gravity(q, **load), rtol=0, atol=TOL_DYN)


@needs_cc
def test_cache_is_reused_across_processes(built, monkeypatch):
    _, _, data, cache = built
    files = list((cache / "models").glob("*/libpanda_model_fer.so"))
    assert len(files) == 1
    mtime = files[0].stat().st_mtime_ns
    monkeypatch.setenv("PANDA_PY_CACHE", str(cache))
    monkeypatch.setattr(clib, "_memory", {})  # as a fresh process would start
    assert model_library("fer") == data
    assert files[0].stat().st_mtime_ns == mtime  # read, not rebuilt


@needs_cc
@pytest.mark.timeout(60)
def test_parallel_processes_build_into_one_cache(tmp_path):
    script = textwrap.dedent(
        """
        import hashlib
        from panda_py.robots.clib import model_library
        print(hashlib.sha256(model_library("fr3")).hexdigest())
        """
    )
    env = {**os.environ, "PANDA_PY_CACHE": str(tmp_path)}
    procs = [
        subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE, text=True)
        for _ in range(3)
    ]
    digests = {p.communicate(timeout=50)[0].strip() for p in procs}
    assert all(p.returncode == 0 for p in procs)
    assert len(digests) == 1
    assert len(list(tmp_path.glob("models/*/libpanda_model_fr3.so"))) == 1
    assert not list(tmp_path.glob("models/*/.build-*"))  # temporaries cleaned up


@needs_cc
def test_source_compiles_without_warnings(tmp_path):
    src = tmp_path / "model.c"
    src.write_text(c_source("fr3"))
    cc = shutil.which("cc") or shutil.which("gcc")
    proc = subprocess.run(
        [cc, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-fsyntax-only", str(src)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr


def test_foreign_platforms_are_unavailable():
    assert HOST is not None
    foreign = next(a for a in Architecture if a is not HOST[0])
    with pytest.raises(ModelLibraryUnavailable, match=foreign.name) as info:
        model_library("fer", architecture=int(foreign), system=int(HOST[1]))
    assert info.value.architecture == foreign
    with pytest.raises(ModelLibraryUnavailable, match="WINDOWS"):
        model_library("fer", architecture=int(HOST[0]), system=int(System.WINDOWS))
    with pytest.raises(ModelLibraryUnavailable, match="unknown architecture 9"):
        model_library("fer", architecture=9, system=0)


def test_missing_compiler_is_unavailable(monkeypatch, tmp_path):
    if HOST is None or HOST[1] is not System.LINUX:
        pytest.skip("only Linux hosts build model libraries")
    monkeypatch.setenv("PANDA_PY_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(ModelLibraryUnavailable, match="no-such-cc"):
        model_library("fer", architecture=int(HOST[0]), system=int(HOST[1]))
    monkeypatch.delenv("CC")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(ModelLibraryUnavailable, match="no C compiler found"):
        model_library("fer", architecture=int(HOST[0]), system=int(HOST[1]))


def test_failing_compiler_is_unavailable(monkeypatch, tmp_path):
    if HOST is None or HOST[1] is not System.LINUX or shutil.which("false") is None:
        pytest.skip("needs a Linux host with `false`")
    monkeypatch.setenv("PANDA_PY_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", "false")
    with pytest.raises(ModelLibraryUnavailable, match="exit status 1"):
        model_library("fer", architecture=int(HOST[0]), system=int(HOST[1]))
    assert not list(tmp_path.glob("models/*/*.so"))


def test_invalid_arguments():
    with pytest.raises(ValueError, match="robot"):
        c_source("ur5")
    with pytest.raises(ValueError, match="robot"):
        model_library("ur5")
    with pytest.raises(ValueError, match="architecture"):
        model_library("fer", architecture="x64")  # type: ignore[arg-type]


def test_source_is_generated_from_params():
    src = c_source("fer")
    for link in FER.links[1:]:
        assert repr(link.mass) in src
        for v in link.inertia:
            assert repr(v) in src
    assert f"#define FLANGE_D {FER.dh.flange_d!r}" in src
