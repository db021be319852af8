#!/usr/bin/env python3
"""Screenshot of a running web map (``--web``) in Debian's chromium via Playwright.

    fleetctl deploy --mission missions/recon.yaml --web 127.0.0.1:8080 &
    scripts/web_screenshot.py http://127.0.0.1:8080/ map.png --wait 10
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("url")
    ap.add_argument("out", help="PNG file to write")
    ap.add_argument("--wait", type=float, default=5.0, help="seconds on the page before the shot")
    ap.add_argument("--size", default="1400x800", help="viewport WIDTHxHEIGHT")
    args = ap.parse_args()
    chromium = shutil.which("chromium")
    if chromium is None:
        print("chromium not found (apt-get install -y chromium)", file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    width, height = (int(x) for x in args.size.split("x"))
    with tempfile.TemporaryDirectory() as profile, sync_playwright() as p:
        viewport = {"width": width, "height": height}
        browser = p.chromium.launch_persistent_context(profile, executable_path=chromium, headless=True,
                                                       args=FLAGS, viewport=viewport)
        try:
            page = browser.new_page()
            page.goto(args.url, timeout=30_000)
            page.wait_for_timeout(args.wait * 1000)
            page.screenshot(path=args.out)
        finally:
            browser.close()
    print(f"screenshot written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
