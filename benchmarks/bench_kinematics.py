"""Time panda_py.kinematics as installed (the default: the numba JIT where numba is
installed) against panda-python 1.1.1 (its C++ fk/ik) in the same run.

Run: ``python benchmarks/bench_kinematics.py [--repeat 3] [--configs 2000] [--batch 10000]``
(``--plain`` also times the plain-Python backend; ``PANDA_PY_NO_JIT=1`` makes it the
default one).

Per call: each sample times a block of calls cycling over ``--configs`` random
configurations (their poses for ik), giving the per-call time; over many samples the
median, p99 and worst [us], for us and for panda-python (run in its own virtual
environment, created by ``tests/peer_envs.py`` if missing, as a subprocess with the same
timing code), and the ratio of the medians. Each figure is measured ``--repeat`` times,
alternating us and the peer; the ratio is printed per repeat (the spread on a shared
machine). Batched: one call over N configurations against panda-python's loop over the
same N, per configuration.

Fresh processes (subprocesses): ``import panda_py``; the first ``fk`` call with the
kernel cache in place; the one-time compile (first ``fk``, and ``warmup()``, with an
empty cache directory).

ik with an unknown q7 (``--search-only`` runs just this case): ``--search-poses`` poses
(500), each ``fk`` of a configuration drawn uniformly within the FER's joint limits
(``numpy.random.default_rng(--search-seed)``, seed 0), so every pose is reachable. Ours:
``ik(O_T_EE, q7_search=math.inf)`` (q_init START_POSE, the search from q_7 = pi/4 over
joint 7's whole range), single and batched (one call over all poses); the peer: frankik
1.0.1's ``FrankaKinematics("panda").inverse(O_T_F, q0=START_POSE)`` (its default q7
sampling, 61 q7 within 20 deg of q0's; and, as thorough as ours, its sampling set to
joint 7's whole range in our step), given the flange pose ``O_T_EE F_T_EE^-1`` exactly
(its own hand offset rounds 1/sqrt(2) to 0.707), in its own virtual environment.
Per pose: each call timed alone ``--search-passes`` times, the pose's median over them;
printed the mean, median, p99 and worst over the poses [us]; batched (and frankik's loop),
a pass's CPU time (``time.thread_time``: the pass takes milliseconds, and its wall time on
a shared machine counts other jobs' turns) / poses, over the passes. Found: a finite
answer within the joint limits whose ``fk`` matches the pose within ``FOUND_TOL`` in every
entry (translation [m], rotation [-]), out of the poses.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

# The timing code, run both here and in the peer's interpreter (so both pay the same
# Python-side overheads). measure(fn, samples, block) -> [per-call seconds]; fn(i) is
# called with i cycling over range(n).
TIMING = """
import time
def measure(fn, samples, block, n):
    for i in range(min(n, 10 * block)):
        fn(i % n)
    out = []
    clock = time.perf_counter
    i = 0
    for _ in range(samples):
        t0 = clock()
        for _ in range(block):
            fn(i)
            i = i + 1 if i + 1 < n else 0
        out.append((clock() - t0) / block)
    return out

def per_call(kin, Q, TT, q7, samples, block):
    n = len(Q)
    fk, ik, ik_full = kin.fk, kin.ik, kin.ik_full
    return {
        "fk": measure(lambda i: fk(Q[i]), samples, block, n),
        "ik": measure(lambda i: ik(TT[i]), samples, block, n),
        "ik_q": measure(lambda i: ik(TT[i], Q[i], q7[i]), samples, block, n),
        "ik_full": measure(lambda i: ik_full(TT[i], Q[i], q7[i]), samples, block, n),
    }
"""

PEER_SCRIPT = (
    TIMING
    + """
import json, sys
import numpy as np
import panda_py
args = json.load(sys.stdin)
Q = [np.array(q) for q in args["Q"]]
TT = [np.array(T) for T in args["TT"]]
q7 = args["q7"]
res = per_call(panda_py, Q, TT, q7, args["samples"], args["block"])
B = np.array(args["QB"]); TB = np.array(args["TB"]); q7b = args["q7b"]
def loop_fk():
    for x in B:
        panda_py.fk(x)
def loop_ik():
    for i in range(len(B)):
        panda_py.ik(TB[i], B[i], q7b[i])
def loop_ik_full():
    for i in range(len(B)):
        panda_py.ik_full(TB[i], B[i], q7b[i])
for name, fn in (("fk", loop_fk), ("ik_q", loop_ik), ("ik_full", loop_ik_full)):
    res["batch_" + name] = [min(measure(lambda i: fn(), 3, 1, 1)) / len(B)]
print(json.dumps(res))
"""
)


# --- ik with an unknown q7 -------------------------------------------------------------

# A solution is found when fk(q) matches the pose within this [m, -] in every entry: the
# tolerance the package's tests hold fk(ik(T)) to (tests/kinematics/).
FOUND_TOL = 1e-9

# Timing run here and in the peer's interpreter. per_pose: each call of fn(i) timed alone,
# `passes` times over all poses; each pose's median over the passes [s] (a call of tens of
# us rarely loses the core, and the median drops those that did). per_pass: fn() over all
# poses, its thread's CPU time / poses [s]: a pass takes milliseconds, and on a shared
# machine its wall time counts the other jobs' turns on the cores.
SEARCH_TIMING = """
import time
def per_pose(fn, n, passes):
    for i in range(n):
        fn(i)
    clock = time.perf_counter
    t = [[0.0] * passes for _ in range(n)]
    for p in range(passes):
        for i in range(n):
            t0 = clock()
            fn(i)
            t[i][p] = clock() - t0
    return [sorted(x)[passes // 2] for x in t]

def per_pass(fn, n, passes):
    fn()
    clock = time.thread_time
    out = []
    for _ in range(passes):
        t0 = clock()
        fn()
        out.append((clock() - t0) / n)
    return out
"""

FRANKIK_SCRIPT = (
    SEARCH_TIMING
    + """
import json, sys
import numpy as np
from frankik import FrankaKinematics
args = json.load(sys.stdin)
kin = FrankaKinematics("panda")
TF = [np.array(T) for T in args["TF"]]
q0 = np.array(args["q0"])
n, passes = len(TF), args["passes"]
inverse = kin.inverse
whole = {"q7_sample_interval": args["interval"], "q7_sample_size": args["size"]}
def answers(**kw):
    out = (inverse(T, q0, **kw) for T in TF)
    return [None if q is None else [float(x) for x in q] for q in out]
def loop():
    for T in TF:
        inverse(T, q0)
print(json.dumps({
    "q": answers(),
    "single": per_pose(lambda i: inverse(TF[i], q0), n, passes),
    "loop": per_pass(loop, n, passes),
    "q_whole": answers(**whole),
    "whole": per_pose(lambda i: inverse(TF[i], q0, **whole), n, max(1, passes // 5)),
}))
"""
)


def _found(kin: Any, Q: np.ndarray, T: np.ndarray) -> int:
    """How many rows of Q (NaN where none) are solutions of their poses T: within the
    joint limits and fk within FOUND_TOL."""
    ok = np.isfinite(Q).all(axis=1)
    Qf = np.where(ok[:, None], Q, 0.0)
    lo, hi = np.array(kin.get_kinematics().q_min), np.array(kin.get_kinematics().q_max)
    ok &= ((Qf >= lo) & (Qf <= hi)).all(axis=1)
    ok &= np.abs(kin.fk(Qf) - T).max(axis=(1, 2)) <= FOUND_TOL
    return int(ok.sum())


def _nan_rows(answers: list[list[float] | None]) -> np.ndarray:
    """frankik's answers (None where it found none) as (N, 7), NaN rows for None."""
    return np.array([[math.nan] * 7 if q is None else q for q in answers])


def search_figures(args: argparse.Namespace) -> None:
    """ik with an unknown q7: ours single and batched against frankik 1.0.1, --repeat
    times alternating (see the module docstring)."""
    import panda_py.kinematics as kin
    from panda_py.robots.params import FER, START_POSE

    kin.warmup()
    ns: dict[str, Any] = {}
    exec(SEARCH_TIMING, ns)
    per_pose, per_pass = ns["per_pose"], ns["per_pass"]
    n, passes = args.search_poses, args.search_passes
    rng = np.random.default_rng(args.search_seed)
    lo, hi = np.array(FER.joints.q_min), np.array(FER.joints.q_max)
    T = kin.fk(rng.uniform(lo, hi, size=(n, 7)))
    TT = list(T)
    TF = T @ np.linalg.inv(kin.hand_F_T_EE())  # the flange poses, for frankik
    try:
        from peer_envs import PeerUnavailable, peer_environ, peer_python

        python: Path | None = peer_python("frankik")
    except (ImportError, PeerUnavailable) as exc:
        print(f"frankik unavailable, no peer figures: {exc}")
        python = None
    # frankik over joint 7's whole range in our step: its interval [deg] and samples
    q7_range = FER.joints.q_max[6] - FER.joints.q_min[6]
    payload = json.dumps({
        "TF": TF.tolist(), "q0": list(START_POSE), "passes": passes,
        "interval": math.degrees(q7_range), "size": round(q7_range / kin.Q7_SEARCH_STEP),
    })  # fmt: skip
    ik, inf = kin.ik, math.inf
    rows: list[tuple[str, list[float], int]] = []
    for rep in range(args.repeat):
        single = per_pose(lambda i: ik(TT[i], q7_search=inf), n, passes)
        found = _found(kin, np.array([ik(Ti, q7_search=inf) for Ti in TT]), T)
        rows.append((f"ours single      #{rep + 1}", single, found))
        batched = per_pass(lambda: ik(T, q7_search=inf), n, passes)
        rows.append((f"ours batched     #{rep + 1}", batched, _found(kin, ik(T, q7_search=inf), T)))
        if python is not None:
            out = subprocess.run(
                [str(python), "-c", FRANKIK_SCRIPT],
                input=payload,
                capture_output=True,
                text=True,
                check=True,
                timeout=1200,
                env=peer_environ(),
            )
            res = json.loads(out.stdout)
            found = _found(kin, _nan_rows(res["q"]), T)
            rows.append((f"frankik 1.0.1    #{rep + 1}", res["single"], found))
            rows.append((f"frankik loop     #{rep + 1}", res["loop"], found))
            found = _found(kin, _nan_rows(res["q_whole"]), T)
            rows.append((f"frankik whole q7 #{rep + 1}", res["whole"], found))
    print(
        f"\nik with an unknown q7: {n} poses, fk of configurations uniform within the FER's "
        f"joint limits (seed {args.search_seed}), q_init START_POSE; [us per pose]"
    )
    print(
        "single: over the poses, each pose's median over the passes; batched (ours, one call) "
        "and loop (frankik's, no batch API): over the passes, each the pass's CPU time / poses; "
        "frankik whole q7: q7_sample_interval/_size set to joint 7's whole range in "
        f"{kin.Q7_SEARCH_STEP} rad steps (a fifth of the passes)"
    )
    print(f"{'':<22}{'mean':>9}{'median':>9}{'p99':>9}{'worst':>9}   found/{n} "
          f"(fk within {FOUND_TOL:g})")  # fmt: skip
    medians: dict[str, list[float]] = {}
    for name, t, found in sorted(rows, key=lambda r: r[0]):
        m, p, w = _stats(t)
        medians.setdefault(name.split("#")[0].strip(), []).append(m)
        print(f"{name:<22}{np.mean(t) * 1e6:9.1f}{m:9.1f}{p:9.1f}{w:9.1f}   {found}")
    if python is not None:
        for ours, theirs in (("ours single", "frankik 1.0.1"), ("ours batched", "frankik loop")):
            ratios = " ".join(
                f"{b / a:.1f}x" for a, b in zip(medians[ours], medians[theirs], strict=True)
            )
            print(f"median speed-up, {ours} against {theirs}, per repeat: {ratios}")


def _stats(samples: list[float]) -> tuple[float, float, float]:
    a = np.asarray(samples) * 1e6
    return float(np.median(a)), float(np.percentile(a, 99)), float(a.max())


def _subprocess_seconds(code: str, **env: str) -> float:
    """Run code in a fresh interpreter; it prints a duration [s] on its last line."""
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={**os.environ, **env},
        timeout=600,
        check=True,
    )
    return float(out.stdout.split()[-1])


IMPORT = "import time; t = time.perf_counter(); import panda_py; print(time.perf_counter() - t)"
FIRST_FK = (
    "import time; t = time.perf_counter(); import numpy as np, panda_py; "
    "panda_py.fk(np.zeros(7)); print(time.perf_counter() - t)"
)
WARMUP = (
    "import time; t = time.perf_counter(); import panda_py.kinematics as k; "
    "k.warmup(); print(time.perf_counter() - t)"
)


def fresh_process_figures(repeat: int) -> None:
    imports = [_subprocess_seconds(IMPORT) for _ in range(max(5, repeat))]
    _subprocess_seconds(FIRST_FK)  # make sure the cache holds fk's kernel
    first = [_subprocess_seconds(FIRST_FK) for _ in range(max(3, repeat))]
    print("\nfresh process [ms]                        min   median      max")
    for name, t in (("import panda_py", imports), ("first fk (kernel cached)", first)):
        a = np.asarray(t) * 1e3
        print(f"{name:<38}{a.min():8.1f}{np.median(a):9.1f}{a.max():9.1f}")
    with tempfile.TemporaryDirectory() as cache:
        cold_fk = _subprocess_seconds(FIRST_FK, PANDA_PY_CACHE=cache)
    with tempfile.TemporaryDirectory() as cache:
        cold_all = _subprocess_seconds(WARMUP, PANDA_PY_CACHE=cache)
        warm_all = _subprocess_seconds(WARMUP, PANDA_PY_CACHE=cache)
    print(f"{'first fk, empty cache (one-time compile)':<38}{cold_fk * 1e3:8.0f}")
    print(f"{'warmup(), empty cache (every kernel)':<38}{cold_all * 1e3:8.0f}")
    print(f"{'warmup(), cache in place':<38}{warm_all * 1e3:8.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=200, help="samples per per-call figure")
    ap.add_argument("--block", type=int, default=100, help="calls per sample")
    ap.add_argument("--configs", type=int, default=2000, help="random configurations cycled")
    ap.add_argument("--batch", type=int, default=10_000, help="N for the batched figures")
    ap.add_argument("--repeat", type=int, default=3, help="repeats of everything (spread)")
    ap.add_argument("--plain", action="store_true", help="also time the plain backend")
    ap.add_argument("--no-fresh", action="store_true", help="skip the subprocess figures")
    ap.add_argument("--search-only", action="store_true", help="only ik with an unknown q7")
    ap.add_argument("--search-poses", type=int, default=500, help="poses of that case")
    ap.add_argument("--search-passes", type=int, default=5, help="timed passes over them")
    ap.add_argument("--search-seed", type=int, default=0, help="their configurations' seed")
    args = ap.parse_args()
    if args.search_only:
        search_figures(args)
        return

    ns: dict[str, object] = {}
    exec(TIMING, ns)
    per_call = ns["per_call"]

    import panda_py.kinematics as kin
    from panda_py.kinematics import _backend
    from panda_py.robots.params import FER

    kin.warmup()
    rng = np.random.default_rng(0)
    lo, hi = np.array(FER.joints.q_min), np.array(FER.joints.q_max)
    Qa = rng.uniform(lo, hi, size=(args.configs, 7))
    Q = list(Qa)
    TT = list(kin.fk(Qa))
    q7 = Qa[:, 6].tolist()
    QB = rng.uniform(lo, hi, size=(args.batch, 7))
    TB = kin.fk(QB)
    q7b = QB[:, 6].copy()

    default = _backend.jit()
    backends: dict[str, object] = {"default (numba JIT)" if default else "default (plain)": default}
    if args.plain and default is not None:
        backends["plain (PANDA_PY_NO_JIT=1)"] = None

    try:
        from peer_envs import PeerUnavailable, peer_python

        python: Path | None = peer_python("panda-python")
    except (ImportError, PeerUnavailable) as exc:
        print(f"panda-python unavailable, no ratios: {exc}")
        python = None
    payload = json.dumps({
        "Q": Qa.tolist(), "TT": [T.tolist() for T in TT], "q7": q7, "samples": args.samples,
        "block": args.block, "QB": QB.tolist(), "TB": TB.tolist(), "q7b": q7b.tolist(),
    })  # fmt: skip

    # results[backend][name] = list over repeats of sample lists; theirs[name] likewise
    results: dict[str, dict[str, list[list[float]]]] = {b: {} for b in backends}
    theirs: dict[str, list[list[float]]] = {}
    for _ in range(args.repeat):
        for bname, mod in backends.items():
            _backend._JIT = mod
            got = per_call(kin, Q, TT, q7, args.samples, args.block)  # type: ignore[operator]
            batched = {
                "batch_fk": lambda: kin.fk(QB),
                "batch_ik_q": lambda: kin.ik(TB, QB, q7b),
                "batch_ik_full": lambda: kin.ik_full(TB, QB, q7b),
            }
            measure = ns["measure"]
            for name, fn in batched.items():
                t = measure(lambda i, fn=fn: fn(), 3, 1, 1)  # type: ignore[operator]
                got[name] = [min(t) / args.batch]
            for name, v in got.items():
                results[bname].setdefault(name, []).append(v)
        _backend._JIT = default
        if python is not None:
            out = subprocess.run(
                [str(python), "-c", PEER_SCRIPT],
                input=payload,
                capture_output=True,
                text=True,
                check=True,
                timeout=1200,
            )
            for name, v in json.loads(out.stdout).items():
                theirs.setdefault(name, []).append(v)

    print(f"\n{args.configs} random configurations, {args.repeat} repeats; per call [us]")
    for bname, ours in results.items():
        print(f"\n=== {bname} ===")
        print(f"{'':<10}{'median':>8}{'p99':>8}{'worst':>8}   panda-python  median"
              f"{'p99':>8}{'worst':>8}   ours/theirs per repeat")  # fmt: skip
        for name in ("fk", "ik", "ik_q", "ik_full"):
            m, p, w = _stats([x for rep in ours[name] for x in rep])
            line = f"{name:<10}{m:8.2f}{p:8.2f}{w:8.2f}"
            if name in theirs:
                tm, tp, tw = _stats([x for rep in theirs[name] for x in rep])
                ratios = [
                    _stats(a)[0] / _stats(b)[0]
                    for a, b in zip(ours[name], theirs[name], strict=True)
                ]
                spread = " ".join(f"{r:.2f}" for r in ratios)
                line += f"   {tm:20.2f}{tp:8.2f}{tw:8.2f}   {spread}"
            print(line)
        print(f"batched, N = {args.batch} [us per configuration]  panda-python loop  "
              "speed-up per repeat")  # fmt: skip
        for name in ("batch_fk", "batch_ik_q", "batch_ik_full"):
            mine = [rep[0] * 1e6 for rep in ours[name]]
            line = f"{name.replace('batch_', ''):<10}{np.median(mine):8.3f}"
            if name in theirs:
                peer = [rep[0] * 1e6 for rep in theirs[name]]
                spread = " ".join(f"{b / a:.1f}x" for a, b in zip(mine, peer, strict=True))
                line += f"{np.median(peer):26.3f}   {spread}"
            print(line)
    print("(ik: default q_init and q_7; ik_q and ik_full: with q_init and q_7)")
    search_figures(args)
    if not args.no_fresh:
        fresh_process_figures(args.repeat)


if __name__ == "__main__":
    main()
