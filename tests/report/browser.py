"""Test helper: a real headless Chromium (Debian's chromium-headless-shell) driven by Playwright.

Playwright's own browser download cannot run here, so the tests use Debian's build, installed
by :func:`chromium_path` when it is missing (apt-get; ``apt-get update`` only if the first try
fails). WebGL runs on SwiftShader (software), so no GPU or display is needed.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

from tool_install import install_lock

CHROMIUM = Path("/usr/lib/chromium/chromium-headless-shell")
"""The real binary (``/usr/bin/chromium-headless-shell`` is a shell wrapper around it)."""

LAUNCH_ARGS = [
    "--no-sandbox",  # root in a container: Chromium's sandbox needs user namespaces
    "--use-angle=swiftshader",  # WebGL in software
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-gpu-sandbox",
]


def _apt_install() -> subprocess.CompletedProcess[str]:
    return subprocess.run(["apt-get", "install", "-y", "chromium-headless-shell"],
                          capture_output=True, text=True, check=False)


def chromium_path() -> Path:
    """Path of Debian's headless Chromium, installing the package first if it is missing.

    Raises
    ------
    RuntimeError
        If it cannot be installed (the test then fails: a missing tool is installed, never skipped).
    """
    if CHROMIUM.is_file():
        return CHROMIUM
    if shutil.which("apt-get") is None:
        raise RuntimeError(f"{CHROMIUM} is missing and apt-get is not available to install chromium-headless-shell")
    with install_lock("chromium-apt"):  # a second worker would fail on dpkg's lock
        if CHROMIUM.is_file():
            return CHROMIUM
        done = _apt_install()
        if done.returncode != 0:
            subprocess.run(["apt-get", "update"], capture_output=True, text=True, check=False)
            done = _apt_install()
    if done.returncode != 0 or not CHROMIUM.is_file():
        raise RuntimeError(f"could not install chromium-headless-shell:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
    return CHROMIUM


@contextmanager
def launch_browser() -> Iterator[object]:
    """A running headless Chromium (Playwright ``Browser``), closed on exit."""
    from playwright.sync_api import sync_playwright

    executable = chromium_path()
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(executable), args=LAUNCH_ARGS, headless=True)
        try:
            yield browser
        finally:
            browser.close()


@dataclass
class PageWatch:
    """What a page did that a test checks: console errors, uncaught exceptions, outside requests."""

    console_errors: list[str] = field(default_factory=list)
    page_errors: list[str] = field(default_factory=list)
    blocked_requests: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)

    def problems(self) -> list[str]:
        return ([f"console error: {m}" for m in self.console_errors]
                + [f"page error: {m}" for m in self.page_errors]
                + [f"network request outside this machine: {u}" for u in self.blocked_requests])


def _is_local(url: str) -> bool:
    parts = urlsplit(url)
    if parts.scheme in ("file", "data", "blob", "about"):
        return True
    return parts.scheme in ("http", "https") and parts.hostname in ("127.0.0.1", "localhost", "::1")


@contextmanager
def open_page(browser: object, url: str, *, width: int = 800, height: int = 700) -> Iterator[tuple[object, PageWatch]]:
    """Open ``url`` in a fresh context that aborts (and records) every request leaving this machine."""
    context = browser.new_context(viewport={"width": width, "height": height}, device_scale_factor=1)
    watch = PageWatch()

    def route(route_obj: object) -> None:
        request_url = route_obj.request.url
        watch.requests.append(request_url)
        if _is_local(request_url):
            route_obj.continue_()
        else:
            watch.blocked_requests.append(request_url)
            route_obj.abort()

    context.route("**/*", route)
    page = context.new_page()
    page.on("console", lambda msg: watch.console_errors.append(msg.text) if msg.type == "error" else None)
    page.on("pageerror", lambda exc: watch.page_errors.append(str(exc)))
    try:
        page.goto(url)
        yield page, watch
    finally:
        context.close()
