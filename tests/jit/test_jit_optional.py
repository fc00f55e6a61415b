"""The one loader of the compiled modules (panda_py.jit.optional): one switch
(PANDA_PY_NO_JIT), numba's absence read as "run plain", any other import error a bug that
surfaces, a module that builds on another loaded only with it, its warm-up run once."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from panda_py import jit

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def modules(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A directory on the path with stand-in kernel modules, forgotten afterwards."""
    sources = {
        "fake_kernels": "WARMED = []\ndef warmup():\n    WARMED.append(1)\n",
        "fake_no_numba": "import numba_that_is_not_installed\n",
        "fake_broken": "import a_typo_of_ours\n",
    }
    for name, text in sources.items():
        (tmp_path / f"{name}.py").write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in sources:
        monkeypatch.delitem(sys.modules, name, raising=False)
        monkeypatch.delitem(jit.LOADED, name, raising=False)
    monkeypatch.delenv(jit.ENV, raising=False)
    return tmp_path


def test_a_module_loads_once_and_warms_once(modules: Path) -> None:
    first = jit.optional("fake_kernels", warm="warmup")
    assert first is not None and first.WARMED == [1]
    assert jit.optional("fake_kernels", warm="warmup") is first  # remembered
    assert first.WARMED == [1]
    assert jit.LOADED["fake_kernels"] is first


def test_the_switch_turns_every_module_off(modules: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for value, on in (("", True), ("0", True), ("1", False), ("yes", False)):
        monkeypatch.setenv(jit.ENV, value)
        assert jit.enabled() is on
    monkeypatch.setenv(jit.ENV, "1")
    assert jit.optional("fake_kernels") is None
    assert "fake_kernels" not in sys.modules  # not even imported


def test_a_missing_compiler_runs_plain_but_our_own_import_error_surfaces(
    modules: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(jit, "_COMPILERS", ("numba_that_is_not_installed",))
    assert jit.optional("fake_no_numba") is None
    with pytest.raises(ImportError, match="a_typo_of_ours"):
        jit.optional("fake_broken")
    assert "fake_broken" not in jit.LOADED  # asked again, it raises again


def test_a_module_that_builds_on_another_needs_it(modules: Path) -> None:
    assert jit.optional("fake_kernels", requires=lambda: None) is None
    assert "fake_kernels" not in sys.modules


def test_no_numba_is_imported_by_the_package_until_a_kernel_is_asked_for() -> None:
    code = textwrap.dedent(
        """
        import sys
        import panda_py, panda_py.jit, panda_py.kinematics, panda_py.controllers
        print("numba" in sys.modules)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr


def test_the_built_in_kernels_all_load_through_it() -> None:
    if not jit.enabled():
        pytest.skip("PANDA_PY_NO_JIT is set")
    from panda_py import dynamics, kinematics
    from panda_py.controllers import laws
    from panda_py.motion import online
    from panda_py.rt import fastloop

    for loaded in (kinematics.compiled_kernels(), dynamics.compiled_kernels(), laws.compiled(),
                   laws.fused(), online.compiled_kernels(), fastloop.kernels(),
                   fastloop.kernel("force_ticks"), fastloop.kernel("pose_move_ticks")):  # fmt: skip
        assert loaded is not None
    for name in ("panda_py.kinematics._numba", "panda_py.dynamics._compiled",
                 "panda_py.controllers._kernels", "panda_py.controllers._fused",
                 "panda_py.motion._online_jit", *fastloop.KERNEL_MODULES):  # fmt: skip
        assert jit.LOADED[name] is sys.modules[name]
