"""The compiled loops' helpers (panda_py.jit.stack, panda_py.jit.libc.copy) and the loop
kernels' compile options: the kernels run without numba's reference counting
(``jit.libc.LOOP_KERNEL``), so every helper they call must compile there too."""

from __future__ import annotations

import importlib

import numba
import numpy as np
import pytest

from panda_py.jit import libc
from panda_py.jit.stack import stack_array
from panda_py.rt import fastloop


@numba.njit(_nrt=False)
def _uses_stack(x):  # type: ignore[no-untyped-def]
    a = stack_array(7)
    for i in range(7):
        a[i] = x * i
    b = stack_array(3)
    libc.copy(b, 0, a[4:], 0, 3)  # a view of a stack array, copied into another
    return a.sum(), a.shape[0], b[0] + b[2]


def test_a_stack_array_works_where_reference_counting_is_off() -> None:
    total, n, ends = _uses_stack(2.0)
    assert (total, n, ends) == (42.0, 7, 8.0 + 12.0)


def test_the_compiled_copy_copies_as_a_slice_does_and_refuses_out_of_bounds() -> None:
    rng = np.random.default_rng(1)
    src = rng.integers(0, 255, 3000).astype(np.uint8)
    dst = np.zeros(4096, np.uint8)
    libc.copy(dst, 100, src, 7, 2373)
    expected = np.zeros(4096, np.uint8)
    expected[100:2473] = src[7:2380]
    assert np.array_equal(dst, expected)
    values = np.zeros((2, 5))
    libc.copy(values[1], 1, np.arange(3.0), 0, 3)
    assert values.tolist() == [[0.0] * 5, [0.0, 0.0, 1.0, 2.0, 0.0]]
    for args in ((dst, 4000, src, 0, 100), (dst, 0, src, 2990, 11), (dst, -1, src, 0, 1),
                 (dst, 0, src, 0, -1)):  # fmt: skip
        before = dst.copy()
        with pytest.raises(IndexError, match="out of its arrays' bounds"):
            libc.copy(*args)
        assert np.array_equal(dst, before)  # nothing written


def test_every_loop_kernel_runs_without_reference_counting() -> None:
    if fastloop.kernels() is None:
        pytest.skip("the loop kernels need numba")
    names = []
    for module_name in fastloop.KERNEL_MODULES:
        module = importlib.import_module(module_name)
        for name in dir(module):
            kernel = getattr(module, name)
            if name.endswith("_ticks") and hasattr(kernel, "targetoptions"):
                assert kernel.targetoptions.get("_nrt") is False, f"{module_name}.{name}"
                names.append(name)
    assert {"cartesian_impedance_ticks", "joint_move_ticks", "pose_move_ticks"} <= set(names)
    from panda_py.sim import _lockstep_jit  # (the simulator's lockstep ticks: the same)

    assert _lockstep_jit.lockstep_ticks.targetoptions.get("_nrt") is False
