"""The keyed disk cache of the compiled kernels (panda_py.jit.cache): the key covers every
source file a kernel compiles, so an edit to any of them selects a new directory."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from panda_py import dynamics, jit, kinematics
from panda_py.controllers import laws
from panda_py.jit import cache as jitcache


def test_the_key_changes_with_any_file_and_only_then(tmp_path: Path) -> None:
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("X = 1\n")
    b.write_text("Y = 2\n")
    key = jitcache.source_key([a, b])
    assert key == jitcache.source_key([b, a])  # the order given does not matter
    b.write_text("Y = 3\n")
    assert jitcache.source_key([a, b]) != key
    b.write_text("Y = 2\n")
    assert jitcache.source_key([a, b]) == key
    assert jitcache.source_key([a]) != key


def test_the_cache_lives_under_panda_py_cache(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PANDA_PY_CACHE", str(tmp_path))
    assert jitcache.cache_dir("k1") == tmp_path / "numba" / "k1"
    monkeypatch.delenv("PANDA_PY_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert jitcache.cache_dir("k1") == tmp_path / "xdg" / "panda_py" / "numba" / "k1"


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_fused_law_is_keyed_over_the_kinematics_and_the_dynamics_it_compiles() -> None:
    """The fused laws inline the Jacobian (kinematics), the recursions (dynamics), the
    online generator's sampling, and read PoseImpedance's buffer at its layout's offsets
    (tracking), with their temporaries on the stack (jit.stack): an edit to any of them
    must compile them afresh."""
    from panda_py.controllers import tracking
    from panda_py.jit import stack
    from panda_py.motion import _online_jit

    fused = laws.fused()
    assert fused is not None
    kin, dyn = kinematics.compiled_kernels(), dynamics.compiled_kernels()
    sources = [Path(fused.__file__), Path(laws.compiled().__file__), Path(dyn.__file__),
               Path(tracking.__file__), Path(_online_jit.__file__), Path(stack.__file__),
               *Path(kin.__file__).parent.glob("*.py")]  # fmt: skip
    assert fused.KEY == jitcache.source_key(sources)
    fused.warmup()
    assert fused.cartesian_impedance_step.stats.cache_path == str(jitcache.cache_dir(fused.KEY))


def test_every_compiled_module_caches_under_a_key_over_its_own_file() -> None:
    """The laws, the dynamics, the online generator's helpers and the simulator's tick
    compile nothing from elsewhere but the stack arrays' helper (jit.stack): each is keyed
    over its file (and that helper's, where it uses it), so a fresh checkout of the same
    sources loads what an earlier one compiled, and an edit compiles afresh."""
    import panda_py.controllers._kernels as kernels
    import panda_py.dynamics._compiled as compiled
    import panda_py.motion._online_jit as online
    import panda_py.sim._tick_jit as tick
    from panda_py.jit import stack

    helper = [Path(stack.__file__)]
    for module, kernel, extra in ((kernels, kernels.finalize_torques, helper),
                                  (compiled, compiled.rnea, helper),
                                  (online, online.publish_pose, helper),
                                  (tick, tick.fill_state, [])):  # fmt: skip
        assert module.KEY == jitcache.source_key([Path(module.__file__), *extra]), module.__name__
        assert kernel.stats.cache_path == str(jitcache.cache_dir(module.KEY)), module.__name__


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: no loop kernels load")
def test_the_loops_that_call_the_c_library_are_keyed_over_its_intrinsics() -> None:
    """The control loop's ticks and the simulator's lockstep ticks call the C library
    through one module's intrinsics (jit.libc): both keys cover it, so an edit to a call's
    declaration compiles both afresh instead of loading machine code made for the old."""
    import panda_py.rt._tick as loop
    import panda_py.rt._tick_laws as controllers
    import panda_py.rt._tick_moves as moves
    import panda_py.rt._tick_wrench as wrench
    import panda_py.sim._lockstep_jit as lockstep
    from panda_py.controllers import condition_program
    from panda_py.jit import libc
    from panda_py.motion import rotation
    from panda_py.sim import compiled

    own = [Path(loop.__file__), Path(libc.__file__)]
    assert loop.KEY.startswith(jitcache.source_key(own))
    # (the laws' loop kernels, on the loop's skeleton: keyed over it too; the moves' also
    # over the guarded moves' condition program and the rotation's quaternion, whose
    # sources they compile)
    for module in (controllers, wrench):
        assert module.KEY.startswith(jitcache.source_key([Path(module.__file__)])), module.__name__
        assert loop.KEY[:20] in module.KEY
    compiled_here = [Path(moves.__file__), Path(condition_program.__file__),
                     Path(rotation.__file__)]  # fmt: skip
    assert moves.KEY.startswith(jitcache.source_key(compiled_here))
    assert loop.KEY[:20] in moves.KEY
    sources = jitcache.source_key([Path(lockstep.__file__), Path(libc.__file__)]) + compiled.KEY
    assert lockstep.KEY == hashlib.sha256(sources.encode()).hexdigest()[:20]
