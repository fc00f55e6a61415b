"""Every code block of the documentation site runs: each page's ```python blocks (and an
``.rst`` page's ``.. code-block:: python``) run in order, in one namespace, against a
simulated robot with a locked Desk, unless a marker on the line before the block says
otherwise (the README's blocks run in ``tests/examples/test_readme.py``):

``<!-- docs-test: alone -->``
    a block that starts its own simulator: it runs in a namespace of its own (a
    ``"127.0.0.2"`` in it becomes a free loopback address), and its ``sim`` is stopped.
``<!-- docs-test: pytest -->``
    a test module: pytest runs it, in a process of its own, and it must pass.
``<!-- docs-test: run by tests/PATH.py -->``
    another test runs it; that file must exist and name the page.
``<!-- docs-test: skip: REASON -->``
    not runnable here, for the reason given (a real robot, a policy server, a cluster).

(In ``.rst`` pages the marker is a comment: ``.. docs-test: skip: REASON``.) The page's
namespace starts with ``hostname``, ``username`` and ``password``: a block that logs into
the Desk sees the Desk's address as ``hostname`` (the simulated Desk serves on a free
port, a robot's on 443), every other block the FCI's. On a page that logs into the Desk
the robot starts locked, so a Desk block that does not unlock it fails the page; on the
others it starts ready.
"""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.desk import DEFAULT_PASSWORD, DEFAULT_USER, DeskConfig

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
KINDS = ("run", "alone", "pytest", "run by", "skip")
MD_BLOCK = re.compile(
    r"(?:^<!-- docs-test: (?P<marker>.*?) -->\n)?^```(?P<lang>\w*)[^\n]*\n(?P<code>.*?)^```",
    flags=re.S | re.M,
)
RST_BLOCK = re.compile(
    r"(?:^\.\. docs-test: (?P<marker>[^\n]*)\n\n?)?^\.\. code(?:-block)?:: (?P<lang>\w+)\n"
    r"(?:[ \t]+:[^\n]*\n)*\n(?P<code>(?:(?:[ \t]+[^\n]*)?\n)+)",
    flags=re.M,
)


@dataclasses.dataclass(frozen=True)
class Block:
    page: str  # relative to the repository
    line: int
    code: str
    kind: str  # one of KINDS
    detail: str  # the reason of a skip, the test of a "run by"


def parse_marker(marker: str | None, where: str) -> tuple[str, str]:
    """The kind and detail of a block's marker (``None``: no marker, the block runs)."""
    if marker is None:
        return "run", ""
    marker = marker.strip()
    if marker in ("alone", "pytest"):
        return marker, ""
    if marker.startswith("run by "):
        return "run by", marker.removeprefix("run by ").strip()
    if marker.startswith("skip:") and marker.removeprefix("skip:").strip():
        return "skip", marker.removeprefix("skip:").strip()
    raise ValueError(
        f"{where}: docs-test marker {marker!r} is not one of 'alone', 'pytest', "
        "'run by tests/...', 'skip: <reason>'"
    )


def page_blocks(path: Path, root: Path = ROOT) -> list[Block]:
    """The python blocks of one page (``.md`` or ``.rst``), in order, with their markers."""
    text = path.read_text()
    page = path.relative_to(root).as_posix()
    blocks = []
    pattern = RST_BLOCK if path.suffix == ".rst" else MD_BLOCK
    for match in pattern.finditer(text):
        if match["lang"] not in ("python", "py"):
            if match["marker"] is not None:
                raise ValueError(f"{page}: a docs-test marker before a {match['lang']!r} block")
            continue
        line = text[: match.start("code")].count("\n") + 1
        kind, detail = parse_marker(match["marker"], f"{page}:{line}")
        code = match["code"]
        if path.suffix == ".rst":  # the directive's body, dedented
            lines = code.splitlines()
            indent = min(len(x) - len(x.lstrip()) for x in lines if x.strip())
            code = "\n".join(x[indent:] for x in lines).strip("\n") + "\n"
        blocks.append(Block(page, line, code, kind, detail))
    return blocks


def pages() -> list[Path]:
    found = [*DOCS.rglob("*.md"), *DOCS.rglob("*.rst")]
    return sorted(p for p in found if "_build" not in p.relative_to(DOCS).parts)


ALL = [block for page in pages() for block in page_blocks(page)]
RUN_PAGES = sorted({b.page for b in ALL if b.kind in ("run", "alone", "pytest")})


def test_the_reader_finds_blocks_and_markers(tmp_path: Path) -> None:
    md = tmp_path / "page.md"
    md.write_text(
        "# A page\n\n```python\nx = 1\n```\n\n```bash\nls\n```\n\n"
        "<!-- docs-test: skip: needs a real robot -->\n```python\nrobot()\n```\n\n"
        "<!-- docs-test: alone -->\n```python\ny = 2\n```\n"
    )
    rst = tmp_path / "page.rst"
    rst.write_text(
        "Title\n=====\n\n.. docs-test: pytest\n\n.. code-block:: python\n   :caption: x\n\n"
        "   def test_x():\n       assert True\n\nAfter.\n"
    )
    assert [(b.line, b.code, b.kind, b.detail) for b in page_blocks(md, tmp_path)] == [
        (4, "x = 1\n", "run", ""),
        (13, "robot()\n", "skip", "needs a real robot"),
        (18, "y = 2\n", "alone", ""),
    ]
    (block,) = page_blocks(rst, tmp_path)
    assert (block.page, block.kind) == ("page.rst", "pytest")
    assert block.code == "def test_x():\n    assert True\n"
    md.write_text("<!-- docs-test: skip -->\n```python\nx\n```\n")  # no reason
    with pytest.raises(ValueError, match="not one of"):
        page_blocks(md, tmp_path)


def test_the_site_has_blocks_to_run_and_every_marker_holds() -> None:
    assert {"docs/tutorial.md", "docs/beyond.md", "docs/simulator.md"} <= set(RUN_PAGES)
    for block in ALL:
        if block.kind == "run by":
            test = ROOT / block.detail
            assert test.is_file(), f"{block.page}:{block.line}: {block.detail} does not exist"
            assert Path(block.page).name in test.read_text(), (
                f"{block.page}:{block.line}: {block.detail} does not name {block.page}"
            )


def test_the_guides_code_parses_and_the_examples_they_name_exist() -> None:
    for block in ALL:
        compile(block.code, f"{block.page}:{block.line}", "exec")  # a SyntaxError names it
    for page in pages():
        for name in re.findall(r"examples/(\w+\.py)", page.read_text()):
            assert (ROOT / "examples" / name).is_file(), f"{page.name} names examples/{name}"


def _stop(ns: dict) -> None:
    for name in ("panda", "gripper", "sim"):
        obj = ns.get(name)
        for method in ("close", "stop"):
            if callable(getattr(obj, method, None)) and not isinstance(obj, type):
                try:
                    getattr(obj, method)()
                except Exception:  # already closed, or never connected: nothing to end
                    pass
                break


def _run_alone(block: Block) -> None:
    ns: dict = {"__name__": "__docs__"}
    try:
        exec(compile(block.code.replace('"127.0.0.2"', repr(free_loopback_host())),
                     f"{block.page}:{block.line}", "exec"), ns)  # fmt: skip
    finally:
        _stop(ns)


def _run_pytest(block: Block, tmp_path: Path) -> None:
    test = tmp_path / f"test_docs_block_{block.line}.py"
    test.write_text(block.code)
    path = os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", str(test)],
        capture_output=True, text=True, timeout=150, cwd=tmp_path, env=env,
    )  # fmt: skip
    assert done.returncode == 0 and " passed" in done.stdout, (
        f"{block.page}:{block.line}:\n{done.stdout}\n{done.stderr}"
    )


@pytest.mark.timeout(300)
@pytest.mark.parametrize("page", RUN_PAGES)
def test_the_page_blocks_run(page: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("PANDA_PY_DESK_DIR", str(tmp_path / "tokens"))
    blocks = [b for b in ALL if b.page == page]
    shared = [b for b in blocks if b.kind == "run"]
    for block in (b for b in blocks if b.kind == "alone"):
        _run_alone(block)
    for block in (b for b in blocks if b.kind == "pytest"):
        _run_pytest(block, tmp_path)
    if not shared:
        return
    # locked where the page unlocks it: its Desk block must then do what it says
    locked = any("Desk(" in b.code for b in shared)
    config = DeskConfig(port=0, locked=locked, cert_dir=str(tmp_path / "cert"))
    with Simulator(free_loopback_host(), lockstep=True, desk=config) as sim:
        assert sim.desk is not None
        ns: dict = {"__name__": "__docs__", "hostname": sim.host,
                    "username": DEFAULT_USER, "password": DEFAULT_PASSWORD}  # fmt: skip
        try:
            for block in shared:
                desk = "Desk(" in block.code
                ns["hostname"] = sim.desk.hostname if desk else sim.host
                exec(compile(block.code, f"{block.page}:{block.line}", "exec"), ns)
                if desk:  # the Desk started locked: the page's moves need this block
                    assert sim.desk.status()["fci"]["active"], f"{page}: the FCI is inactive"
        finally:
            _stop(ns)
