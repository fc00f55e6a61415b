"""The simulated Desk's page in a real headless browser (Playwright driving Debian's
chromium): log in, see the status, take control, unlock, activate the FCI, watch the arm
move, recover from a safety error, press the Pilot to confirm a forced take.

Skipped where the browser is missing, except in CI (``CI=true``), where the README's
command installs it (``.ci/ensure-browser``) and a missing browser is a failure.
"""

from __future__ import annotations

import math
import os
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from panda_py.desk import Desk
from panda_py.robots import START_POSE
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(180)
CHROMIUM = os.environ.get("PANDA_PY_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run",
]  # fmt: skip
WAIT = 5000  # [ms] for the page to show a change


def _missing(reason: str) -> None:
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI must run the browser test: see .ci/ensure-browser)")
    pytest.skip(reason)


@pytest.fixture
def page(tmp_path: Path) -> Iterator[Any]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("playwright is not installed (pip install -e '.[dev]')")
    if not os.path.exists(CHROMIUM):
        _missing(f"no chromium at {CHROMIUM} (apt-get install chromium)")
    with sync_playwright() as pw:
        context = pw.chromium.launch_persistent_context(
            str(tmp_path / "profile"),  # a fresh user-data-dir
            executable_path=CHROMIUM,
            args=CHROMIUM_ARGS,
            headless=True,
            ignore_https_errors=True,  # the robot's certificate is self-signed
        )
        try:
            yield context.new_page()
        finally:
            context.close()


def test_the_page_drives_the_robot(page: Any, fer: Simulator, tmp_path: Path) -> None:
    from playwright.sync_api import expect

    assert fer.desk is not None
    fer.desk.power_cycle()
    fer.set_joint_positions(START_POSE)
    page.goto(fer.desk.url + "/")
    page.fill("#login-user", "franka")
    page.fill("#login-password", "wrong")
    page.click("#login-button")
    expect(page.locator("#message")).to_have_text("wrong user name or password", timeout=WAIT)
    page.fill("#login-password", "franka123")
    page.click("#login-button")
    expect(page.locator("#desk-panel")).to_be_visible(timeout=WAIT)
    expect(page.locator("#status-brakes")).to_have_text("Locked", timeout=WAIT)
    expect(page.locator("#status-fci")).to_have_text("Inactive")
    expect(page.locator("#status-owner")).to_have_text("nobody")

    page.click("#take")
    expect(page.locator("#status-owner")).to_have_text("franka", timeout=WAIT)
    page.click("#fci-on")  # the brakes are closed: refused, nothing changes
    expect(page.locator("#message")).to_contain_text("424", timeout=WAIT)
    expect(page.locator("#status-fci")).to_have_text("Inactive")
    page.click("#unlock")
    expect(page.locator("#status-brakes")).to_have_text("Unlocked", timeout=WAIT)
    page.click("#fci-on")
    expect(page.locator("#status-fci")).to_have_text("Active", timeout=WAIT)
    status = fer.desk.status()
    assert status["safety"]["brakeState"][0] == "Unlocked" and status["fci"]["active"]

    # the joint positions and the end-effector pose update live
    q = list(START_POSE)
    q[0] = 0.5
    fer.set_joint_positions(q)
    expect(page.locator("#joints li").first).to_have_text(f"{math.degrees(0.5):.2f}", timeout=WAIT)
    x, y = (float(v) for v in fer.state()["O_T_EE"][12:14])
    expect(page.locator("#ee-position")).to_contain_text(f"y {y:.4f} m", timeout=WAIT)
    assert x > 0

    # a safety error shows, and is recovered from the page
    fer.desk.inject_safety_error()
    expect(page.locator("#status-errors")).to_have_text("SafetyError", timeout=WAIT)
    expect(page.locator("#status-brakes")).to_have_text("Locked", timeout=WAIT)
    page.click("#recover")
    expect(page.locator("#status-errors")).to_have_text("none", timeout=WAIT)

    # a client forces its way in; the person at the robot confirms on the page's Pilot
    client = Desk(fer.desk.hostname, "franka", "franka123", token_dir=str(tmp_path / "c"))
    assert not client.has_control()
    taken: list[bool] = []
    worker = threading.Thread(target=lambda: taken.append(client.take_control(force=True)))
    worker.start()
    try:
        for _ in range(500):  # until the forced request waits for the Pilot
            if fer.desk.status()["pendingControlRequests"]:
                break
            page.wait_for_timeout(20)
        page.click("#pilot-circle")
    finally:
        worker.join(10)
    assert taken == [True] and client.has_control()
    page.click("#unlock")  # the page no longer holds the token
    expect(page.locator("#message")).to_contain_text("423", timeout=WAIT)
    client.release_control()
    expect(page.locator("#status-owner")).to_have_text("nobody", timeout=WAIT)
    page.click("#logout")
    expect(page.locator("#login-panel")).to_be_visible(timeout=WAIT)
