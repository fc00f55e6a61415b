"""Time panda_py.dynamics (pure Python) and the generated C model library (via ctypes).

Run: ``python benchmarks/bench_dynamics.py [--n 5000]``. Prints mean, p99 and worst case
per call in microseconds. The C library is compiled (and cached) on first use; its row is
skipped when no C compiler is available.
"""

from __future__ import annotations

import argparse
import ctypes
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from panda_py import dynamics
from panda_py.robots.clib import ModelLibraryUnavailable, model_library
from panda_py.robots.params import GRAVITY


def _measure(fn: Callable[[], object], n: int) -> tuple[float, float, float]:
    for _ in range(min(n // 10, 200)):
        fn()
    samples = np.empty(n)
    clock = time.perf_counter
    for k in range(n):
        t0 = clock()
        fn()
        samples[k] = clock() - t0
    us = samples * 1e6
    return float(us.mean()), float(np.percentile(us, 99)), float(us.max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=5000, help="calls per function")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    q, dq, ddq = rng.uniform(-2, 2, (3, 7))
    load = {"m_load": 0.73, "F_x_Cload": (-0.01, 0.0, 0.03)}
    I = np.diag([0.001, 0.0025, 0.0017])
    cases: dict[str, Callable[[], object]] = {
        "py gravity": lambda: dynamics.gravity(q, **load),
        "py coriolis": lambda: dynamics.coriolis(q, dq, I_load=I, **load),
        "py mass_matrix": lambda: dynamics.mass_matrix(q, I_load=I, **load),
        "py inverse_dynamics": lambda: dynamics.inverse_dynamics(q, dq, ddq, I_load=I, **load),
    }
    try:
        data = model_library("fer")
    except ModelLibraryUnavailable as exc:
        print(f"(C library skipped: {exc})")
    else:
        path = Path(tempfile.mkdtemp()) / "model.so"
        path.write_bytes(data)
        lib = ctypes.CDLL(str(path))
        vec = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
        lib.g_NE.argtypes = [vec, vec, ctypes.c_double, vec, vec]
        lib.M_NE.argtypes = [vec, vec, ctypes.c_double, vec, vec]
        g_earth, c, I_col = np.array(GRAVITY), np.array(load["F_x_Cload"]), I.ravel()
        out7, out49 = np.zeros(7), np.zeros(49)
        cases["C g_NE (ctypes)"] = lambda: lib.g_NE(q, g_earth, 0.73, c, out7)
        cases["C M_NE (ctypes)"] = lambda: lib.M_NE(q, I_col, 0.73, c, out49)
    print(f"{'function':<24}{'mean us':>10}{'p99 us':>10}{'worst us':>10}")
    for name, fn in cases.items():
        mean, p99, worst = _measure(fn, args.n)
        print(f"{name:<24}{mean:>10.1f}{p99:>10.1f}{worst:>10.1f}")


if __name__ == "__main__":
    main()
