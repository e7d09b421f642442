"""Headless Chromium driven over the DevTools protocol, to test report pages as a user sees
them: console errors, uncaught exceptions, network requests, a screenshot, real mouse input.

Imported as the top-level module ``browser`` (conftest puts this directory on sys.path).
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import shutil
import subprocess
import tempfile
import urllib.request
from dataclasses import dataclass, field
from typing import Any

from tornado.websocket import websocket_connect


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def install_chromium() -> str | None:
    """Debian's ``chromium`` package, installed with apt-get when missing (as root); None when
    it cannot be installed here."""
    found = find_chromium()
    if found or shutil.which("apt-get") is None or os.geteuid() != 0:
        return found
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for cmd in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", "chromium"]):
        try:
            subprocess.run(cmd, env=env, check=True, capture_output=True, timeout=900)
        except (OSError, subprocess.SubprocessError):
            return None
    return find_chromium()


@dataclass
class PageReport:
    """What a page did while it loaded and was used."""

    console_errors: list[str] = field(default_factory=list)
    exceptions: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)  # every URL the page asked for
    results: list[Any] = field(default_factory=list)  # of the steps, in order
    screenshot: bytes = b""


class _Session:
    def __init__(self, ws) -> None:
        self.ws = ws
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    async def call(self, method: str, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        my_id = self.next_id
        await self.ws.write_message(json.dumps({"id": my_id, "method": method,
                                                "params": params}))
        while True:
            raw = await asyncio.wait_for(self.ws.read_message(), 30)
            if raw is None:
                raise RuntimeError("chromium closed the DevTools connection")
            msg = json.loads(raw)
            if msg.get("id") == my_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    async def wait_for(self, method: str, timeout: float = 30) -> None:
        if any(e.get("method") == method for e in self.events):
            return
        while True:
            raw = await asyncio.wait_for(self.ws.read_message(), timeout)
            if raw is None:
                raise RuntimeError("chromium closed the DevTools connection")
            msg = json.loads(raw)
            self.events.append(msg)
            if msg.get("method") == method:
                return

    async def evaluate(self, expression: str) -> Any:
        out = await self.call("Runtime.evaluate", expression=expression, returnByValue=True,
                              awaitPromise=True)
        if "exceptionDetails" in out:
            raise RuntimeError(f"{expression!r}: {out['exceptionDetails']}")
        return out["result"].get("value")


class Chromium:
    """One headless Chromium for all the tests of a session; each page gets its own tab."""

    def __init__(self, executable: str) -> None:
        self.profile = tempfile.mkdtemp(prefix="lander-chromium-")
        self.proc = subprocess.Popen(
            [executable, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--remote-debugging-port=0", f"--user-data-dir={self.profile}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )
        self.port = None
        for line in self.proc.stderr:  # "DevTools listening on ws://127.0.0.1:PORT/devtools/..."
            match = re.search(r"ws://127\.0\.0\.1:(\d+)/", line)
            if match:
                self.port = int(match.group(1))
                break
        if self.port is None:
            self.close()
            raise RuntimeError("chromium did not open its DevTools port")

    def _http(self, path: str, method: str = "GET") -> Any:
        request = urllib.request.Request(f"http://127.0.0.1:{self.port}{path}", method=method)
        with urllib.request.urlopen(request, timeout=30) as r:
            body = r.read()
        return json.loads(body) if body.strip().startswith((b"{", b"[")) else body

    def inspect(self, url: str, steps: list | None = None,
                size: tuple[int, int] = (1600, 1300)) -> PageReport:
        """Load ``url`` in a new tab, run ``steps`` (``("eval", JS)`` or ``("hover", CSS
        selector)``), take a screenshot, and report what the page did."""
        target = self._http("/json/new?about:blank", method="PUT")
        try:
            return asyncio.run(self._inspect(target["webSocketDebuggerUrl"], url,
                                             list(steps or []), size))
        finally:
            self._http(f"/json/close/{target['id']}")

    async def _inspect(self, ws_url: str, url: str, steps: list,
                       size: tuple[int, int]) -> PageReport:
        ws = await websocket_connect(ws_url, max_message_size=1 << 28)
        s = _Session(ws)
        for domain in ("Runtime", "Log", "Page", "Network"):
            await s.call(f"{domain}.enable")
        await s.call("Emulation.setDeviceMetricsOverride", width=size[0], height=size[1],
                     deviceScaleFactor=1, mobile=False)
        await s.call("Page.navigate", url=url)
        await s.wait_for("Page.loadEventFired")
        report = PageReport()
        for kind, arg in steps:
            if kind == "eval":
                report.results.append(await s.evaluate(arg))
            elif kind == "hover":  # move the real mouse over the centre of an element
                box = await s.evaluate(
                    f"(function(){{var r=document.querySelector({json.dumps(arg)})"
                    ".getBoundingClientRect();return [r.x+r.width/2,r.y+r.height/2];})()")
                await s.call("Input.dispatchMouseEvent", type="mouseMoved", x=box[0], y=box[1])
                report.results.append(box)
        shot = await s.call("Page.captureScreenshot", format="png")
        report.screenshot = base64.b64decode(shot["data"])
        await s.evaluate("1")  # collect the events the last steps caused
        for e in s.events:
            method, params = e.get("method"), e.get("params", {})
            if method == "Runtime.exceptionThrown":
                report.exceptions.append(json.dumps(params.get("exceptionDetails"))[:500])
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error",
                                                                                 "assert"):
                report.console_errors.append(json.dumps(params.get("args"))[:500])
            elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
                report.console_errors.append(params["entry"].get("text", "")[:500])
            elif method == "Network.requestWillBeSent":
                report.requests.append(params["request"]["url"][:200])
        ws.close()
        return report

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        shutil.rmtree(self.profile, ignore_errors=True)


