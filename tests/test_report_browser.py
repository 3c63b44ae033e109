"""summary.html in headless Chromium: no console errors, no network, the class table equals
class_summary.csv, fits a phone screen, prints to PDF. Skipped when Chromium is absent."""
from __future__ import annotations

import base64
import json
import os
import re
import shutil
import struct
import subprocess
import time
import urllib.request

import pandas as pd
import pytest
from click.testing import CliRunner

import test_fleet_fakes as fakes
from fleetrun.cli import cli
from fleetrun.run import runner
from test_fleet_fakes import scenario, vehicle, write_fleet

pytestmark = pytest.mark.browser
CHROMIUM = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)
if CHROMIUM is None:
    pytest.skip("chromium is not installed", allow_module_level=True)


class WebSocket:
    """The few bits of RFC 6455 a DevTools client needs (text frames, client masking), so the
    test needs no extra package."""

    def __init__(self, url: str, timeout: float = 30):
        import socket
        from urllib.parse import urlparse

        parts = urlparse(url)
        self.sock = socket.create_connection((parts.hostname, parts.port), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET {parts.path} HTTP/1.1\r\nHost: {parts.hostname}:{parts.port}\r\n"
                           "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
        response = b""
        while b"\r\n\r\n" not in response:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("websocket handshake failed")
            response += chunk
        head, _, self.pending = response.partition(b"\r\n\r\n")
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise ConnectionError(head.decode(errors="replace"))

    def settimeout(self, seconds):
        self.sock.settimeout(seconds)

    def _read(self, n: int) -> bytes:
        while len(self.pending) < n:
            chunk = self.sock.recv(max(65536, n - len(self.pending)))
            if not chunk:
                raise ConnectionError("websocket closed")
            self.pending += chunk
        data, self.pending = self.pending[:n], self.pending[n:]
        return data

    def _frame(self, opcode: int, payload: bytes) -> None:
        mask = os.urandom(4)
        n = len(payload)
        header = bytes([0x80 | opcode])
        if n < 126:
            header += bytes([0x80 | n])
        elif n < 1 << 16:
            header += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            header += bytes([0x80 | 127]) + struct.pack(">Q", n)
        self.sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def send(self, text: str) -> None:
        self._frame(0x1, text.encode())

    def recv(self) -> str:
        message = b""
        while True:
            first, second = self._read(2)
            n = second & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._read(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._read(8))[0]
            payload = self._read(n)  # servers do not mask
            opcode = first & 0x0F
            if opcode == 0x9:        # ping
                self._frame(0xA, payload)
                continue
            if opcode == 0x8:
                raise ConnectionError("websocket closed by the browser")
            message += payload
            if first & 0x80:
                return message.decode()

    def close(self):
        self.sock.close()


class Browser:
    """Just enough of the DevTools protocol: commands, and the events they produce."""

    def __init__(self, profile_dir):
        self.process = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--disable-dev-shm-usage", f"--user-data-dir={profile_dir}", "--remote-debugging-port=0",
             "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        port = None
        deadline = time.time() + 30
        while time.time() < deadline and port is None:
            line = self.process.stderr.readline()
            found = re.search(r"DevTools listening on ws://[^:]+:(\d+)/", line)
            if found:
                port = int(found.group(1))
        if port is None:
            self.close()
            pytest.fail("chromium did not start its DevTools endpoint")
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10))
        page = next(t for t in targets if t["type"] == "page")
        self.ws = WebSocket(page["webSocketDebuggerUrl"], timeout=30)
        self.next_id = 0
        self.events: list[dict] = []

    def send(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.recv())
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self.events.append(message)

    def wait_for(self, method, timeout=30):
        deadline = time.time() + timeout
        while time.time() < deadline:
            for i, event in enumerate(self.events):
                if event.get("method") == method:
                    return self.events.pop(i)
            self.ws.settimeout(max(0.1, deadline - time.time()))
            self.events.append(json.loads(self.ws.recv()))
        raise TimeoutError(method)

    def evaluate(self, expression):
        result = self.send("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in result:
            raise RuntimeError(result["exceptionDetails"])
        return result["result"]["value"]

    def problems(self) -> list[str]:
        found = []
        for event in self.events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                found.append(f"exception: {params['exceptionDetails'].get('text')}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "warning", "assert"):
                found.append(f"console.{params['type']}: {params.get('args')}")
            elif method == "Log.entryAdded" and params["entry"]["level"] in ("error", "warning"):
                found.append(f"log {params['entry']['level']}: {params['entry'].get('text')}")
            elif method == "Network.requestWillBeSent":
                url = params["request"]["url"]
                if not url.startswith(("file:", "data:", "about:")):
                    found.append(f"network request: {url}")
        return found

    def close(self):
        try:
            self.ws.close()
        except Exception:
            pass
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return fakes.run_small_fleet_with_fake(tmp_path_factory.mktemp("browser"))


@pytest.fixture
def browser(tmp_path):
    b = Browser(tmp_path / "profile")
    for domain in ("Runtime", "Log", "Network", "Page"):
        b.send(f"{domain}.enable")
    yield b
    b.close()


def open_page(browser, path):
    browser.send("Page.navigate", url=path.resolve().as_uri())
    browser.wait_for("Page.loadEventFired")


CLASS_TABLE_JS = """JSON.stringify([...document.querySelectorAll('#class-table tbody tr')].map(
  tr => Object.fromEntries([...tr.cells].map(td => [td.dataset.column, [td.dataset.value, td.textContent]]))))"""


def test_summary_no_console_errors_and_class_table_equals_csv(browser, run_dir):
    open_page(browser, run_dir / "summary.html")
    assert browser.problems() == []
    rows = json.loads(browser.evaluate(CLASS_TABLE_JS))
    csv = pd.read_csv(run_dir / "class_summary.csv", dtype=str, keep_default_na=False)
    assert len(rows) == len(csv)
    for shown, (_, expected) in zip(rows, csv.iterrows()):
        for column, (value, text) in shown.items():
            assert value == expected[column], column
            if column not in ("scenario_id", "vehicle_class"):
                number = float(text.replace("$", "").replace(",", "").replace("%", ""))
                if text.endswith("%"):
                    number /= 100.0
                assert number == pytest.approx(float(value), rel=5e-3, abs=0.5), column
            else:
                assert text == value
    assert browser.evaluate("document.querySelectorAll('svg.chart').length") >= 3
    assert browser.evaluate("document.getElementById('fingerprint').textContent").strip() != ""


OVERFLOW_JS = """JSON.stringify([...document.querySelectorAll('body, body *')].filter(
  el => el instanceof HTMLElement && getComputedStyle(el).display !== 'inline' && el.clientWidth > 0
        && el.scrollWidth > el.clientWidth + 1).map(
  el => `${el.tagName.toLowerCase()}#${el.id}.${el.className} ${el.scrollWidth}>${el.clientWidth}`))"""


@pytest.mark.parametrize("width, mobile", [(390, True), (1366, False)])
def test_no_block_overflows_at_phone_and_desktop_width(browser, run_dir, width, mobile):
    """Issue 12: the class table overflowed its box at 1366 px and the charts ran off a 390 px
    screen. Every block's content must fit its box (scrollWidth <= clientWidth), the page too."""
    browser.send("Emulation.setDeviceMetricsOverride", width=width, height=900, deviceScaleFactor=1,
                 mobile=mobile)
    open_page(browser, run_dir / "summary.html")
    assert json.loads(browser.evaluate(OVERFLOW_JS)) == []
    assert browser.evaluate("document.documentElement.scrollWidth") <= width
    # chart text stays readable: no SVG text drawn smaller than 8 px on screen
    smallest = browser.evaluate("Math.min(...[...document.querySelectorAll('svg text')].map("
                                "t => t.getBoundingClientRect().height).filter(h => h > 0))")
    assert smallest >= 8


def test_summary_shows_assumptions_fiscal_years_and_one_colour_scale(browser, run_dir):
    open_page(browser, run_dir / "summary.html")
    assert browser.evaluate("document.querySelectorAll('#assumptions tbody tr').length") >= 8
    fiscal = pd.read_csv(run_dir / "fiscal_summary.csv", dtype=str, keep_default_na=False)
    assert browser.evaluate("document.querySelectorAll('table.fiscal tbody tr').length") == len(fiscal)
    assert browser.evaluate("document.querySelectorAll('svg.scale').length") == 1
    cards = browser.evaluate("[...document.querySelectorAll('.card')].map(c => c.textContent).join('|')")
    assert "State fuel tax" in cards and "Federal fuel tax" in cards and " to " in cards


def test_summary_fits_a_phone_and_prints(browser, run_dir):
    browser.send("Emulation.setDeviceMetricsOverride", width=390, height=844, deviceScaleFactor=3, mobile=True)
    open_page(browser, run_dir / "summary.html")
    assert browser.evaluate("document.documentElement.scrollWidth") <= 390
    pdf = base64.b64decode(browser.send("Page.printToPDF", printBackground=True)["data"])
    assert pdf.startswith(b"%PDF") and len(pdf) > 10_000
    assert browser.problems() == []


def test_hostile_labels_stay_text_in_the_browser(browser, tmp_path, monkeypatch):
    label = '<img src=x onerror="console.error(1)"><script>console.error(2)</script>'
    path = write_fleet(tmp_path / "evil.xlsx", [vehicle(vehicle_class=label)],
                       [scenario(description=label)])
    out = tmp_path / "out"
    assert fakes.invoke_run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    open_page(browser, out / "summary.html")
    assert browser.problems() == []
    assert browser.evaluate("document.querySelectorAll('img, script').length") == 0
    cells = json.loads(browser.evaluate(CLASS_TABLE_JS))
    assert cells[0]["vehicle_class"][1] == label


CLIPPED_JS = """JSON.stringify([...document.querySelectorAll('svg')].flatMap(svg => {
  const box = svg.getBoundingClientRect();
  return [...svg.querySelectorAll('text')].map(t => [t.textContent, t.getBoundingClientRect()]).filter(
    ([_, r]) => r.width > 0 && (r.left < box.left - 1 || r.right > box.right + 1 || r.top < box.top - 1
                                || r.bottom > box.bottom + 1)).map(([text, r]) => `${text} ${r.left}-${r.right} of ${box.left}-${box.right}`);
}))"""


@pytest.fixture(scope="module")
def long_labels_run(tmp_path_factory):
    """Class names and scenario ids as long as a state's (the labels that were clipped)."""
    tmp = tmp_path_factory.mktemp("labels")
    path = write_fleet(tmp / "fleet.xlsx",
                       [vehicle("A", vehicle_class="Tractor-trailer (class 8)", fuel="diesel", count=500),
                        vehicle("B", vehicle_class="SUV / crossover", count=2000)],
                       [scenario("baseline"), scenario("hot_summer_heat_wave", ambient_temp_C=38),
                        scenario("congested_urban_growth", cycle_mix="UDDS:1")])
    out = tmp / "out"
    result = fakes.invoke_run(path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    return out


@pytest.mark.parametrize("width, mobile", [(390, True), (1366, False)])
def test_no_chart_text_is_clipped_and_the_memo_table_shows(browser, long_labels_run, width, mobile):
    browser.send("Emulation.setDeviceMetricsOverride", width=width, height=900, deviceScaleFactor=1,
                 mobile=mobile)
    open_page(browser, long_labels_run / "summary.html")
    assert json.loads(browser.evaluate(CLIPPED_JS)) == []
    memo = pd.read_csv(long_labels_run / "revenue_memo.csv")
    assert browser.evaluate("document.querySelectorAll('table.memo tbody tr').length") == len(memo)
    assert browser.evaluate("document.querySelectorAll('svg.tornado').length") == 1
    assert json.loads(browser.evaluate(OVERFLOW_JS)) == []
