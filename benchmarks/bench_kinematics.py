"""Time panda_py.kinematics against panda-python 1.1.1 (its C++ fk/ik) in the same run.

Run: ``python benchmarks/bench_kinematics.py [--samples 300] [--batch 10000]``.

Per call: each sample times a block of calls (the per-call time of the block), over many
samples: median, p99 and worst in microseconds, for us and for panda-python (run in its
own virtual environment, created by ``tests/peer_envs.py`` if missing, as a subprocess
with the same timing code). Batched: one call over N configurations or poses against
panda-python's per-call loop over the same N, per configuration. Also the import time of
``panda_py``. Both backends are timed: the pure-NumPy paths and, if numba is installed
(and PANDA_PY_NO_JIT is not set), the numba kernels; their batches also on one thread
(the serial kernels, which batches below ``PARALLEL_MIN_ROWS`` and busy machines get).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

# The timing code, run both here and in the peer's interpreter (so both pay the same
# Python-side overheads). It defines measure(fn, samples, block) -> [per-call seconds].
TIMING = """
import time
def measure(fn, samples, block):
    for _ in range(block * 10):
        fn()
    out = []
    clock = time.perf_counter
    for _ in range(samples):
        t0 = clock()
        for _ in range(block):
            fn()
        out.append((clock() - t0) / block)
    return out
"""

PEER_SCRIPT = (
    TIMING
    + """
import json, sys, math, time
import numpy as np
import panda_py
args = json.load(sys.stdin)
q = np.array(args["q"]); T = panda_py.fk(q)
res = {
    "fk": measure(lambda: panda_py.fk(q), args["samples"], args["block"]),
    "ik": measure(lambda: panda_py.ik(T), args["samples"], args["block"]),
    "ik_q": measure(lambda: panda_py.ik(T, q, 0.5), args["samples"], args["block"]),
    "ik_full": measure(lambda: panda_py.ik_full(T), args["samples"], args["block"]),
}
Q = np.array(args["Q"]); TT = np.array(args["TT"]); q7 = args["q7"]
def loop_fk():
    for x in Q:
        panda_py.fk(x)
def loop_ik():
    for i in range(len(Q)):
        panda_py.ik(TT[i], Q[i], q7[i])
def loop_ik_full():
    for i in range(len(Q)):
        panda_py.ik_full(TT[i], Q[i], q7[i])
for name, fn in (("fk_loop", loop_fk), ("ik_loop", loop_ik), ("ik_full_loop", loop_ik_full)):
    t = min(measure(fn, 3, 1))
    res[name] = [t / len(Q)]
print(json.dumps(res))
"""
)


def _stats(samples: list[float]) -> tuple[float, float, float]:
    a = np.asarray(samples) * 1e6
    return float(np.median(a)), float(np.percentile(a, 99)), float(a.max())


def _import_time() -> float:
    code = "import time; t = time.perf_counter(); import panda_py; print(time.perf_counter() - t)"
    best = math.inf
    for _ in range(5):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        best = min(best, float(out.stdout))
    return best


def _first_call_time() -> float:
    code = (
        "import time, numpy as np, panda_py; q = np.zeros(7); t = time.perf_counter(); "
        "panda_py.fk(q); print(time.perf_counter() - t)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    return float(out.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=300, help="samples per per-call figure")
    ap.add_argument("--block", type=int, default=100, help="calls per sample")
    ap.add_argument("--batch", type=int, default=10_000, help="N for the batched figures")
    args = ap.parse_args()

    ns: dict[str, object] = {}
    exec(TIMING, ns)
    measure = ns["measure"]

    t0 = time.perf_counter()
    import panda_py.kinematics as kin

    t_kin_import = time.perf_counter() - t0
    from panda_py.kinematics import _model
    from panda_py.robots.params import FER, START_POSE

    q = np.array(START_POSE)
    s, b = args.samples, args.block
    rng = np.random.default_rng(0)
    n = args.batch
    Q = rng.uniform(FER.joints.q_min, FER.joints.q_max, size=(n, 7))
    q7 = Q[:, 6].copy()
    backends: dict[str, object] = {"pure": None}
    t0 = time.perf_counter()
    jit = _model.load_jit()
    t_jit_import = time.perf_counter() - t0
    if jit is not None:
        backends["numba"] = jit
        backends["numba, one thread"] = jit
    par_min = _model.PARALLEL_MIN_ROWS
    results: dict[str, dict[str, list[float]]] = {}
    for bname, mod in backends.items():
        _model._JIT = mod
        _model.PARALLEL_MIN_ROWS = 2**62 if bname == "numba, one thread" else par_min
        T = kin.fk(q)
        TT = kin.fk(Q)
        ours: dict[str, list[float]] = {}
        if bname != "numba, one thread":  # (single calls are the same as "numba")
            ours = {
                "fk": measure(lambda: kin.fk(q), s, b),  # type: ignore[operator]
                "ik": measure(lambda: kin.ik(T), s, b),  # type: ignore[operator]  # noqa: B023
                "ik_q": measure(lambda: kin.ik(T, q, 0.5), s, b),  # type: ignore[operator]  # noqa: B023
                "ik_full": measure(lambda: kin.ik_full(T), s, b),  # type: ignore[operator]  # noqa: B023
                "zero_jacobian": measure(lambda: kin.zero_jacobian(q), s, b),  # type: ignore[operator]
            }
        batched = {
            "fk_loop": lambda: kin.fk(Q),
            "ik_loop": lambda: kin.ik(TT, Q, q7),  # noqa: B023
            "ik_full_loop": lambda: kin.ik_full(TT, Q, q7),  # noqa: B023
            "zero_jacobian_loop": lambda: kin.zero_jacobian(Q),
        }
        for name, fn in batched.items():
            ours[name] = [min(measure(fn, 5, 1)) / n]  # type: ignore[operator]
        results[bname] = ours
    _model._JIT = jit
    _model.PARALLEL_MIN_ROWS = par_min
    T = kin.fk(q)
    TT = kin.fk(Q)

    theirs: dict[str, list[float]] = {}
    try:
        from peer_envs import PeerUnavailable, peer_python

        python = peer_python("panda-python")
        payload = {"q": q.tolist(), "samples": s, "block": b, "Q": Q.tolist(),
                   "TT": TT.tolist(), "q7": q7.tolist()}  # fmt: skip
        out = subprocess.run(
            [str(python), "-c", PEER_SCRIPT],
            input=json.dumps(payload),
            capture_output=True,
            text=True,
            check=True,
            timeout=600,
        )
        theirs = json.loads(out.stdout)
    except (PeerUnavailable, subprocess.SubprocessError) as exc:
        print(f"panda-python unavailable, no ratios: {exc}")

    for bname, ours in results.items():
        print(f"\n=== backend: {bname} ===")
        if "fk" in ours:
            print(f"{'per call [us]':<22}{'median':>9}{'p99':>9}{'worst':>9}   panda-python median"
                  f"{'p99':>8}{'worst':>9}   ours/theirs")  # fmt: skip
        for name in ("fk", "ik", "ik_q", "ik_full", "zero_jacobian"):
            if name not in ours:
                continue
            m, p, w = _stats(ours[name])
            line = f"{name:<22}{m:9.2f}{p:9.2f}{w:9.2f}"
            if name in theirs:
                tm, tp, tw = _stats(theirs[name])
                line += f"   {tm:19.2f}{tp:8.2f}{tw:9.2f}   {m / tm:10.2f}x"
            print(line)
        print(f"batched over N = {n} [us per configuration]   panda-python loop   speed-up")
        for name in ("fk_loop", "ik_loop", "ik_full_loop", "zero_jacobian_loop"):
            m = ours[name][0] * 1e6
            line = f"{name.replace('_loop', ''):<22}{m:9.3f}"
            if name in theirs:
                tm = theirs[name][0] * 1e6
                line += f"   {tm:18.3f}   {tm / m:8.1f}x"
            print(line)
    if jit is None:
        print("\n(numba not installed or PANDA_PY_NO_JIT set: pure backend only)")
    else:
        print(f"\nload numba + cached kernels (this process): {t_jit_import * 1e3:.0f} ms")
        print(f"first fk call in a fresh process (numba import, kernel load): "
              f"{_first_call_time() * 1e3:.0f} ms")  # fmt: skip
    print(f"\nimport panda_py: {_import_time() * 1e3:.1f} ms")
    print(f"import panda_py.kinematics (first, in this process): {t_kin_import * 1e3:.1f} ms")
    print("(ik: O_T_EE of the start pose, default q_init and q_7; ik_q: with q_init and q_7=0.5)")


if __name__ == "__main__":
    main()
