"""Open swarmloc's live view and its run.mcap in a real Lichtblick, as a user would, and fail when
the viewer complains: `make viewer-check LICHTBLICK=DIR` (outside CI: it needs a Lichtblick web
build and Chromium; docs/live-view.md says how to get both).

Four cases, each with the run's own Lichtblick layout (``layout-lichtblick.json``):

- ``live``: a 5-vehicle realtime `swarm up --live`, joined while it flies;
- ``recording``: that run's run.mcap, opened near its end;
- ``camera``: a camera swarm's run.mcap (`swarm experiment vision-slam`: terrain and landmarks);
- ``flight3d``: the 3-D AR-EKF-SLAM flight's run.mcap (`swarm experiment ar-slam`'s 3-D case: the
  relief, the camera and the map's 3-sigma ellipsoids);
- ``uav``: the UAV swarm's run.mcap (`swarm up scenarios/uav-3d.toml`: the UAVs at their heights,
  their maps' ellipsoids).

For each it writes a screenshot, the browser console and what the Alerts tab says, and reads every
plot's legend: each series must show a current value (its data arrived). It fails when the Alerts
tab lists anything, a series has no value, or the page threw. Serves the web app and the runs on
127.0.0.1 only; drives headless Chromium over the DevTools protocol (websockets).
"""

from __future__ import annotations

import argparse
import base64
import functools
import http.server
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SWARM = [sys.executable, "-m", "cli"]
ALERTS_JS = """(async () => {
  const tab = [...document.querySelectorAll('[role=tab]')].find(e => e.innerText.startsWith('Alerts'));
  if (!tab) return 'no alerts tab';
  const count = parseInt(tab.innerText.replace('Alerts', '').trim(), 10) || 0;
  tab.click();
  await new Promise(r => setTimeout(r, 1000));
  const panel = document.querySelector('[role=tabpanel]:not([hidden])')?.innerText ?? '';
  return count ? `${count} alert(s): ${panel || document.body.innerText.slice(0, 1500)}` : panel;
})()"""
LEGENDS_JS = """(() => [...document.querySelectorAll('[data-testid=plot-legend-row-path-label]')].map(label => {
  const row = label.closest('[class*=PlotLegendRow_tsx-root]');
  const value = row && row.querySelector('[class*=MuiTypography-alignRight]');
  return [label.innerText, value ? value.innerText : null];
}))()"""


class _Files(http.server.SimpleHTTPRequestHandler):
    """Static files with CORS and byte ranges (a remote run.mcap is read in ranges)."""

    def end_headers(self) -> None:
        self.send_header("Access-Control-Allow-Origin", "*")
        self.send_header("Access-Control-Allow-Headers", "Range")
        self.send_header("Access-Control-Expose-Headers", "Content-Length, Content-Range, Accept-Ranges")
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Cache-Control", "no-store")
        super().end_headers()

    def do_OPTIONS(self) -> None:  # noqa: N802 (the http.server convention)
        self.send_response(204)
        self.end_headers()

    def send_head(self):
        wanted = re.fullmatch(r"bytes=(\d+)-(\d*)", self.headers.get("Range", ""))
        path = Path(self.translate_path(self.path))
        if wanted is None or not path.is_file():
            return super().send_head()
        size = path.stat().st_size
        start, end = int(wanted.group(1)), min(int(wanted.group(2) or size - 1), size - 1)
        handle = path.open("rb")
        handle.seek(start)
        self.send_response(206)
        self.send_header("Content-Type", self.guess_type(str(path)))
        self.send_header("Content-Range", f"bytes {start}-{end}/{size}")
        self.send_header("Content-Length", str(end - start + 1))
        self.end_headers()
        self._left = end - start + 1
        return handle

    def copyfile(self, source, destination) -> None:
        left = getattr(self, "_left", None)
        if left is None:
            return super().copyfile(source, destination)
        while left > 0 and (chunk := source.read(min(65536, left))):
            destination.write(chunk)
            left -= len(chunk)

    def log_message(self, *args) -> None:
        pass


def serve(directory: Path) -> int:
    """Serve ``directory`` on a free 127.0.0.1 port in a thread; the port."""
    handler = functools.partial(_Files, directory=str(directory))
    handler.extensions_map = {**_Files.extensions_map, ".wasm": "application/wasm", ".mcap": "application/octet-stream"}
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server.server_address[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Browser:
    """Headless Chromium, driven over the DevTools protocol: one tab per page."""

    def __init__(self, chromium: str, profile: Path) -> None:
        self.port = free_port()
        flags = [
            "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--ignore-gpu-blocklist",
            f"--remote-debugging-port={self.port}", "--remote-debugging-address=127.0.0.1",
            f"--user-data-dir={profile}", "--window-size=1600,1000",
        ]  # fmt: skip
        self.process = subprocess.Popen([chromium, *flags], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 30
        while True:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{self.port}/json/version", timeout=2)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise SystemExit("viewer-check: Chromium did not start") from None
                time.sleep(0.3)

    def visit(self, url: str, wait_s: float, shot: Path) -> dict:
        """Open ``url``, wait, screenshot; the console, the exceptions, the alerts and the legends."""
        from websockets.sync.client import connect

        request = urllib.request.Request(f"http://127.0.0.1:{self.port}/json/new?about:blank", method="PUT")
        tab = json.loads(urllib.request.urlopen(request, timeout=10).read())
        console, thrown, replies, counter = [], [], {}, iter(range(1, 10**9))
        with connect(tab["webSocketDebuggerUrl"], max_size=2**28) as ws:

            def call(method: str, **params) -> dict:
                ident = next(counter)
                ws.send(json.dumps({"id": ident, "method": method, "params": params}))
                deadline = time.monotonic() + 120
                while ident not in replies:
                    message = json.loads(ws.recv(timeout=max(0.1, deadline - time.monotonic())))
                    if "id" in message:
                        replies[message["id"]] = message.get("result", message.get("error", {}))
                    elif message.get("method") == "Runtime.consoleAPICalled":
                        args = message["params"]["args"]
                        text = " ".join(str(a.get("value", a.get("description", ""))) for a in args)
                        console.append(f"{message['params']['type']}: {text[:500]}")
                    elif message.get("method") == "Runtime.exceptionThrown":
                        thrown.append(str(message["params"]["exceptionDetails"].get("text", ""))[:500])
                return replies.pop(ident)

            def wait(seconds: float) -> None:
                end = time.monotonic() + seconds
                while time.monotonic() < end:
                    call("Runtime.evaluate", expression="1")
                    time.sleep(0.5)

            for domain in ("Runtime", "Page"):
                call(f"{domain}.enable")
            call("Emulation.setDeviceMetricsOverride", width=1600, height=1000, deviceScaleFactor=1, mobile=False)
            call("Page.navigate", url=url)
            wait(wait_s)
            legends = call("Runtime.evaluate", expression=LEGENDS_JS, returnByValue=True)["result"].get("value")
            shot.write_bytes(base64.b64decode(call("Page.captureScreenshot", format="png")["data"]))
            alerts = call("Runtime.evaluate", expression=ALERTS_JS, awaitPromise=True, returnByValue=True)
            alerts = alerts["result"].get("value", "")
        urllib.request.urlopen(f"http://127.0.0.1:{self.port}/json/close/{tab['id']}", timeout=10)
        return {"legends": legends or [], "alerts": alerts, "console": console, "thrown": thrown}

    def close(self) -> None:
        self.process.terminate()
        self.process.wait(timeout=30)


def problems(name: str, seen: dict) -> list[str]:
    """What makes a case fail: any alert, a series without a current value, an exception."""
    found = []
    alerts = seen["alerts"].strip()
    if alerts and not alerts.lower().startswith("no alerts"):
        found.append(f"{name}: the Alerts tab lists: {alerts[:400]!r}")
    series = [(label, value) for label, value in seen["legends"] if not label.startswith("95 %")]
    if not series:
        found.append(f"{name}: no plot series shown")
    found += [f"{name}: plot series {label!r} has no data" for label, value in series if value in (None, "")]
    found += [f"{name}: the page threw: {text}" for text in seen["thrown"]]
    return found


CASES = ("live", "recording", "camera", "flight3d", "uav")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lichtblick", type=Path, required=True, help="Lichtblick's built web app (web/.webpack)")
    parser.add_argument("--out", type=Path, default=Path("runs/viewer-check"), help="screenshots, logs and runs")
    parser.add_argument("--chromium", default=shutil.which("chromium") or "chromium")
    parser.add_argument("--cases", default=",".join(CASES), help=f"some of {','.join(CASES)} (recording needs live)")
    args = parser.parse_args(argv)
    cases = set(args.cases.split(","))
    if not cases <= set(CASES) or ("recording" in cases and "live" not in cases):
        print(f"viewer-check: --cases takes some of {','.join(CASES)}, recording with live", file=sys.stderr)
        return 2
    if not (args.lichtblick / "index.html").is_file():
        print(f"viewer-check: no Lichtblick web build in {args.lichtblick} (index.html)", file=sys.stderr)
        return 2
    out = args.out.resolve()
    if out.exists() and any(out.iterdir()) and not (out / "viewer-check.json").exists():
        print(f"viewer-check: {out} is not empty and not a previous check's: give another --out", file=sys.stderr)
        return 2
    shutil.rmtree(out, ignore_errors=True)  # a previous check's runs: the run names must be free
    out.mkdir(parents=True)
    app, data = serve(args.lichtblick), serve(out)
    base = f"http://127.0.0.1:{app}/"
    browser = Browser(args.chromium, Path(tempfile.mkdtemp(prefix="viewer-check-")))
    found: list[str] = []
    report: dict[str, dict] = {}

    def swarm(*arguments: str) -> None:
        subprocess.run([*SWARM, *arguments], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)

    def open_recording(run: str, at_s: int, name: str) -> dict:
        """The run's run.mcap (``run`` under ``out``) opened at ``at_s`` with its own layout."""
        where = f"http://127.0.0.1:{data}/{run}"
        url = f"{base}?ds=remote-file&ds.url={where}/run.mcap&time={at_s}&layoutUrl={where}/layout-lichtblick.json"
        return browser.visit(url, 25, out / f"{name}.png")

    try:
        if "live" in cases:
            port = free_port()
            live = subprocess.Popen(
                [*SWARM, "up", "--vehicles", "5", "--duration", "90", "--mode", "realtime", "--live",
                 "--live-port", str(port), "--name", "live", "--out", str(out), "--quiet", "--no-report"],
                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )  # fmt: skip
            deadline = time.monotonic() + 60
            while not (out / "live" / "layout-lichtblick.json").exists() and time.monotonic() < deadline:
                time.sleep(0.5)
            time.sleep(5)
            layout = f"http://127.0.0.1:{data}/live/layout-lichtblick.json"
            url = f"{base}?ds=foxglove-websocket&ds.url=ws://127.0.0.1:{port}&layoutUrl={layout}"
            report["live"] = browser.visit(url, 30, out / "live.png")
            live.send_signal(signal.SIGINT)
            live.wait(timeout=120)
        if "recording" in cases:
            recording = f"http://127.0.0.1:{data}/live/run.mcap"
            report["recording"] = browser.visit(f"{base}?ds=remote-file&ds.url={recording}&time=30&layoutUrl={layout}",
                                                25, out / "recording.png")  # fmt: skip
        if "camera" in cases:
            swarm("experiment", "vision-slam", "--seed", "3", "--duration", "30", "--out", str(out), "--quiet")
            slam = sorted(out.glob("vision-slam*/slam"))[-1].relative_to(out).as_posix()
            report["camera"] = open_recording(slam, 25, "camera")
        if "flight3d" in cases:
            swarm("experiment", "ar-slam", "--cases", "3-D ar-ekf-slam", "--out", str(out), "--quiet")
            report["flight3d"] = open_recording("ar-slam/3-D-ar-ekf-slam", 60, "flight3d")
        if "uav" in cases:
            swarm("up", "scenarios/uav-3d.toml", "--mode", "lockstep", "--name", "uav", "--out", str(out), "--quiet",
                  "--no-report")  # fmt: skip
            report["uav"] = open_recording("uav", 40, "uav")
    finally:
        browser.close()
    for name, seen in report.items():
        found += problems(name, seen)
        (out / f"{name}-console.log").write_text("\n".join(seen["console"]) + "\n")
    (out / "viewer-check.json").write_text(json.dumps(report, indent=2) + "\n")
    for line in found:
        print(line, file=sys.stderr)
    print(f"viewer-check: {'FAILED' if found else 'passed'}; screenshots and logs in {out}")
    return 1 if found else 0


if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    sys.exit(main())
