"""Options several commands share: ``--budget-ms``, the MQTT bus's ``--mqtt``/``--topic-prefix``
and the views' ``--web``/``--tiles``/``--latlon``. Building the parser imports no mission code:
``fleetctl --help`` and a usage error load neither NumPy nor the mission loader."""

from __future__ import annotations

import argparse

from fleetctl.run.budget import DEFAULT_BUDGET_MS


def budget_ms(text: str) -> float:
    """``--budget-ms N``: milliseconds of anytime improvement search after the quick plan."""
    from fleetctl.mission.limits import MAX_BUDGET_MS  # the mission package (NumPy): only when given

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of milliseconds, got {text!r}") from None
    if not 0 <= value <= MAX_BUDGET_MS:
        raise argparse.ArgumentTypeError(f"must be 0..{MAX_BUDGET_MS:.0f} ms, got {text}")
    return value


def add_budget_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--budget-ms", type=budget_ms, metavar="N",
                   help="after the quick plan, improve it for about N ms (iterated local search, seeded "
                        "by planner.seed, ending sooner when it converges; 0: the quick plan; default: the "
                        f"mission's planner.budget_ms, else {DEFAULT_BUDGET_MS:.0f} ms for 'plan' and a "
                        "deployment's first plan, the quick plan for a collection (its rovers hover) and "
                        "for replans)")



def add_bus_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mqtt", metavar="URL",
                   help="publish status, plan, telemetry and events to this MQTT broker and take task "
                        "changes from it (mqtt://HOST[:PORT] or mqtts://HOST[:PORT]; default: the "
                        "mission's mqtt: section; off when neither)")
    p.add_argument("--topic-prefix", metavar="P",
                   help="MQTT topic prefix (default: the mission's mqtt.topic_prefix, "
                        "else fleetctl/<mission name>)")



def add_view_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--web", metavar="HOST:PORT",
                   help="also serve a live map page there (e.g. 127.0.0.1:8080; 0.0.0.0:PORT lets other "
                        "machines see it, with a token: the link printed at start, or "
                        "FLEETCTL_WEB_TOKEN); self-contained, no internet needed")
    p.add_argument("--tiles", metavar="URL",
                   help="with --web: draw map tiles under the map from this XYZ template, e.g. "
                        "http://tiles.local/{z}/{x}/{y}.png (default: none)")
    p.add_argument("--latlon", action="store_true",
                   help="terminal view: latitude/longitude instead of E/N metres")

