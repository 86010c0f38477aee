"""Helpers for the editor tests: a server on a free loopback port, raw HTTP, headless Chromium."""
from __future__ import annotations

import os
import shutil
import socket
import time
from pathlib import Path

import pytest

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 # WebGL without a GPU: Chromium's software rasterizer (SwiftShader)
                 "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]


def chromium_path():
    for name in ("/usr/bin/chromium", "/usr/bin/chromium-browser"):
        if Path(name).exists():
            return name
    return shutil.which("chromium") or shutil.which("chromium-browser")


def require_browser():
    """The Chromium executable and Playwright's sync API; skip (outside CI) if either is missing.

    Under CI (env CI set) a missing browser is a failure: .ci/run installs it."""
    path = chromium_path()
    try:
        from playwright.sync_api import sync_playwright  # noqa: F401
    except ImportError:
        sync_playwright = None
    missing = []
    if path is None:
        missing.append("Debian's chromium (apt-get install chromium)")
    if sync_playwright is None:
        missing.append("Playwright for Python (pip install playwright)")
    if missing:
        reason = "browser tests need " + " and ".join(missing)
        if os.environ.get("CI"):
            pytest.fail(reason + "; under CI .ci/run must install them")
        pytest.skip(reason, allow_module_level=True)
    return path


def require(module, install):
    """Import ``module``; skip the test if it is missing, or fail under CI (which installs it)."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        reason = f"needs {module} ({install})"
        if os.environ.get("CI"):
            pytest.fail(reason + "; under CI the editor's extras must be installed")
        pytest.skip(reason, allow_module_level=True)


def raw_request(url, request_line, headers=None, body=b"", timeout=10.0):
    """Send a request byte for byte (no client-side path normalisation); return (status, body)."""
    host, port = url.split("//", 1)[1].rstrip("/").split(":")
    lines = [request_line, f"Host: {host}:{port}", "Connection: close"]
    for k, v in (headers or {}).items():
        lines.append(f"{k}: {v}")
    if body and not any(k.lower() in ("content-length", "transfer-encoding") for k in (headers or {})):
        lines.append(f"Content-Length: {len(body)}")
    data = ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body
    with socket.create_connection((host, int(port)), timeout=timeout) as s:
        s.sendall(data)
        chunks = []
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                c = s.recv(65536)
            except (ConnectionResetError, TimeoutError):
                break
            if not c:
                break
            chunks.append(c)
    raw = b"".join(chunks)
    head, _, rest = raw.partition(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1]) if head else 0
    return status, rest


def wait_js(page, expression, timeout=20.0):
    """Poll a JavaScript expression until it is truthy (page.evaluate is not subject to the CSP,
    unlike page.wait_for_function's polling)."""
    deadline = time.monotonic() + timeout
    while True:
        value = page.evaluate(expression)
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {expression}")
        time.sleep(0.02)
