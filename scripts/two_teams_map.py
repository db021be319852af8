#!/usr/bin/env python3
"""The screenshot of the web map with every team (docs/two-teams-map.png), from a real run.

Flies ``fleetctl deploy --mission missions/two_carriers.yaml --web 127.0.0.1:PORT`` on the
embedded simulated fleet, opens the map in Debian's chromium (headless, through Playwright) and
takes the shot once every team shows its ETA and at least ``--flying`` rovers of each team have
left their deck; then stops the run (Ctrl-C: the airborne rovers hold, the records are written).

    scripts/two_teams_map.py                          # writes docs/two-teams-map.png
    scripts/two_teams_map.py --out /tmp/map.png --speedup 5 --flying 3
"""

from __future__ import annotations

import argparse
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
LOOK = """() => {
    const teams = [...document.querySelectorAll('#teams [data-team]')];
    const off = {};
    for (const v of document.querySelectorAll('.vehicle.rover[data-team]'))
        if (!['on_deck', 'loaded', 'unknown'].includes(v.dataset.state))
            off[v.dataset.team] = (off[v.dataset.team] || 0) + 1;
    return {teams: teams.map(t => t.dataset.team), etas: teams.filter(t => t.dataset.eta).length, off};
}"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_run(mission: str, speedup: float, run_dir: Path) -> tuple[subprocess.Popen[str], str | None]:
    """The deployment with its map on a free loopback port, and the map's address (None when it
    ended without one). Its output is drained by a thread from then on (a full pipe would stall it)."""
    cmd = [sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", mission, "--headless",
           "--speedup", str(speedup), "--run-dir", str(run_dir), "--web", f"127.0.0.1:{free_port()}"]
    run = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert run.stdout is not None
    url = None
    for line in run.stdout:  # the map's address comes before the flight
        if line.startswith("web map: "):
            url = line.split()[2]
            break
    threading.Thread(target=run.stdout.read, daemon=True).start()
    return run, url


def wait_for_the_moment(page: Any, run: subprocess.Popen[str], flying: int, timeout: float) -> bool:
    """Until every team (at least two) shows its ETA and has ``flying`` rovers off its deck."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and run.poll() is None:
        look = page.evaluate(LOOK)
        teams = look["teams"]
        off = all(look["off"].get(t, 0) >= flying for t in teams)
        if len(teams) >= 2 and look["etas"] == len(teams) and off:
            return True
        page.wait_for_timeout(100)
    return False


def stop_run(run: subprocess.Popen[str]) -> None:
    if run.poll() is None:
        run.send_signal(signal.SIGINT)  # as Ctrl-C: the rovers hold, the records are written
        try:
            run.wait(timeout=60)
        except subprocess.TimeoutExpired:
            run.kill()
            run.wait(timeout=10)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mission", default=str(REPO / "missions" / "two_carriers.yaml"))
    ap.add_argument("--out", default=str(REPO / "docs" / "two-teams-map.png"))
    ap.add_argument("--speedup", type=float, default=5.0, help="simulated seconds per wall second")
    ap.add_argument("--flying", type=int, default=3, help="rovers of each team off their deck at the shot")
    ap.add_argument("--size", default="1400x800", help="viewport WIDTHxHEIGHT")
    ap.add_argument("--timeout", type=float, default=300.0, help="wall seconds to wait for the moment")
    args = ap.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        print("chromium not found (apt-get install -y chromium)", file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    width, height = (int(x) for x in args.size.split("x"))
    with tempfile.TemporaryDirectory() as tmp:
        run, url = start_run(args.mission, args.speedup, Path(tmp) / "run")
        try:
            if url is None:
                print("fleetctl ended without a web map", file=sys.stderr)
                return 1
            with sync_playwright() as p:
                browser = p.chromium.launch_persistent_context(
                    str(Path(tmp) / "profile"), executable_path=chromium, headless=True, args=FLAGS,
                    viewport={"width": width, "height": height})
                try:
                    page = browser.new_page()
                    page.goto(url, timeout=30_000)
                    if not wait_for_the_moment(page, run, args.flying, args.timeout):
                        print("the moment did not come (every team's ETA, rovers off each deck)",
                              file=sys.stderr)
                        return 1
                    page.wait_for_timeout(300)  # the trails of the last frames
                    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
                    page.screenshot(path=args.out)
                finally:
                    browser.close()
        finally:
            stop_run(run)
    print(f"screenshot written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
