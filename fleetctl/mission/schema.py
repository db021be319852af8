"""The mission file's schema: one spec per section (key -> (parser, default or ``REQUIRED``)),
``TOP`` the file itself. docs/mission-file.md documents every key of every spec (a test reads
them). The parsers are in :mod:`fleetctl.mission.values`; the rules across keys and the typed
mission in :mod:`fleetctl.mission.loader`.
"""

from __future__ import annotations

from typing import Any

import fleetctl.mission.limits as L
from fleetctl.geo import Origin
from fleetctl.mission.flight import FIRMWARE_SPEEDS
from fleetctl.mission.model import (
    FAILSAFE_ACTIONS,
    FAULT_KINDS,
    FENCE_ACTIONS,
    LinksConfig,
    PlannerConfig,
    RoadmapConfig,
    SigningConfig,
    TlsConfig,
)
from fleetctl.mission.operation import WORK_MODES
from fleetctl.mission.values import (
    ACCEL,
    ALT,
    ID,
    OPT_STR,
    POINT_SPEC,
    POS,
    RANGE,
    REQUIRED,
    TIME,
    Ctx,
    KeyPath,
    Parser,
    boolean,
    connection_url,
    env_name,
    file_ref,
    integer,
    list_of,
    mqtt_url,
    number,
    one_of,
    type_name,
    vector,
)

ORIGIN = {
    "lat": (number(ge=-90, le=90, unit="degrees"), REQUIRED),
    "lon": (number(ge=-180, le=180, unit="degrees"), REQUIRED),
    "alt": (ALT, REQUIRED),
}
CARRIER = {
    "id": (ID, "carrier"),
    "connection": (connection_url, "sim"),
    "sysid": (integer(1, 255, "MAVLink system id"), 1),
    "position": (vector(2), REQUIRED),
    "heading_deg": (
        number(ge=-L.MAX_HEADING, le=L.MAX_HEADING, unit="compass degrees, 0 = north, 90 = east"), 0.0
    ),
    "max_speed": (POS, REQUIRED),
    "accel": (ACCEL, None),
    "turn_rate": (number(ge=L.MIN_TURN_RATE, le=L.MAX_TURN_RATE, null=True, unit="rad/s"), None),
    "unload_time": (TIME, 0.0),
    "load_time": (TIME, 0.0),
    "swap_time": (TIME, 0.0),
    "deck_height": (number(ge=-L.MAX_DECK_HEIGHT, le=L.MAX_DECK_HEIGHT,
                           unit="m of the deck above the carrier's reported altitude"), 0.0),
    "firmware_speeds": (one_of(*FIRMWARE_SPEEDS), None),
}
ENERGY = {
    "initial": (number(gt=0, le=L.MAX_ENERGY), REQUIRED),
    "task": (number(ge=0, le=L.MAX_ENERGY), REQUIRED),
    "rho": (number(gt=0, le=L.MAX_RHO, unit="metres per unit of energy"), REQUIRED),
}
FLEET = {
    "count": (integer(1, 255, "number of rovers"), None),
    "sysid_start": (integer(1, 255, "MAVLink system id of r1"), None),
}
UNIT = {
    "id": (ID, REQUIRED),
    "sysid": (integer(1, 255, "MAVLink system id"), REQUIRED),
    "connection": (connection_url, None),
}
ROVERS = {
    "max_speed": (POS, REQUIRED),
    "accel": (ACCEL, None),
    "deploy_range": (RANGE, None),
    "energy": (lambda c, v, p: c.section(v, p, ENERGY), None),
    "endurance_range": (RANGE, None),
    "reserve": (number(ge=0, lt=1, unit="fraction of the battery"), 0.1),
    "climb_rate": (number(ge=L.MIN_SPEED, le=L.MAX_SPEED, null=True, unit="m/s"), None),
    "land_speed": (number(ge=L.MIN_SPEED, le=L.MAX_SPEED, null=True, unit="m/s"), None),
    "takeoff_time": (number(ge=0, le=L.MAX_HANDLING_TIME, null=True, unit="s"), None),
    "land_time": (number(ge=0, le=L.MAX_HANDLING_TIME, null=True, unit="s"), None),
    "firmware_speeds": (one_of(*FIRMWARE_SPEEDS), None),
    "work": (one_of(*WORK_MODES), "hover"),
    "fleet": (lambda c, v, p: c.section(v, p, FLEET), None),
    "units": (list_of(lambda c, v, p: c.section(v, p, UNIT), "units {id, sysid, connection}", L.MAX_ROVERS),
              None),
}
TEAM = {**CARRIER, "id": (ID, REQUIRED), "sysid": (CARRIER["sysid"][0], REQUIRED),
         "fleet": ROVERS["fleet"], "units": ROVERS["units"]}  # carriers[i]: a carrier and its rovers
TASK = {"id": (ID, REQUIRED), **POINT_SPEC,
         "duration": (number(ge=0, le=L.MAX_DWELL, null=True, unit="seconds of work; null = dwell"), None),
         "work": (one_of(*WORK_MODES), None)}
COLLECT_ROVER = {
    "id": (ID, REQUIRED),
    **POINT_SPEC,
    "range": (number(gt=0, le=L.MAX_RANGE, unit="metres"), REQUIRED),
}
COLLECTION = {
    "rovers": (
        list_of(lambda c, v, p: c.section(v, p, COLLECT_ROVER), "rovers {id, position, range}", L.MAX_ROVERS),
        REQUIRED,
    )
}
FAULT = {
    "vehicle": (OPT_STR, None),
    "kind": (one_of(*FAULT_KINDS), REQUIRED),
    "at": (number(ge=0, le=L.MAX_SIM_TIME, unit="simulated seconds"), 0.0),
    "until": (number(ge=0, le=L.MAX_SIM_TIME, null=True, unit="simulated seconds; omit = never back"), None),
    "rate": (number(ge=0, le=1, unit="fraction of packets lost"), None),
    "seconds": (number(ge=0, le=L.MAX_LATENCY, unit="added latency in seconds"), None),
    "factor": (number(gt=0, le=L.MAX_DRAIN, unit="battery drain multiplier"), None),
    "level": (number(ge=0, le=1, unit="fraction of a full battery"), None),
    "distance": (number(gt=0, le=L.MAX_DRIFT, unit="metres a landing drifts"), None),
}
FAULT_PARAM = {"packet_loss": "rate", "latency": "seconds", "battery_drain": "factor",
                "low_battery": "level", "land_drift": "distance"}
SIM = {
    "speedup": (number(ge=L.MIN_SPEEDUP, le=L.MAX_SPEEDUP, unit="simulated seconds per wall second"), 1.0),
    "faults": (
        list_of(lambda c, v, p: c.section(v, p, FAULT), "faults {vehicle, kind, ...}", L.MAX_FAULTS), []
    ),
}
SIGNING = {"key_env": (env_name, REQUIRED)}
LINKS = {
    "heartbeat_timeout": (
        number(ge=L.MIN_HEARTBEAT_TIMEOUT, le=L.MAX_HEARTBEAT_TIMEOUT, unit="seconds"), 3.0
    ),
    "reassign_after": (number(ge=0, le=L.MAX_HEARTBEAT_TIMEOUT, unit="seconds"), 10.0),
    "signing": (lambda c, v, p: SigningConfig(**c.section(v, p, SIGNING)), None),
    "failsafe": (one_of(*FAILSAFE_ACTIONS), "keep"),
}
XI = number(ge=0, le=L.MAX_XI)
ROADMAP = {
    "xi1": (XI, None),
    "xi2": (XI, None),
    "xi3": (XI, None),
    "xi4": (XI, None),
    "phi": (number(gt=0, lt=1), None),
}
PLANNER = {
    "deploy": (ID, "lee"),
    "collect": (ID, "lee"),
    "seed": (integer(0, L.MAX_SEED), 0),
    "budget_ms": (number(ge=0, le=L.MAX_BUDGET_MS, null=True, unit="ms of improvement search"), None),
    "roadmap": (lambda c, v, p: RoadmapConfig(**c.section(v, p, ROADMAP)), None),
}
TLS = {"ca": (OPT_STR, None), "cert": (OPT_STR, None), "key": (OPT_STR, None)}
MQTT = {
    "url": (mqtt_url, REQUIRED),
    "topic_prefix": (OPT_STR, None),
    "client_id": (OPT_STR, None),
    "username": (OPT_STR, None),
    "password_env": (OPT_STR, None),
    "tls": (lambda c, v, p: TlsConfig(**c.section(v, p, TLS)), None),
    "accept_task_changes": (boolean, False),
}
TASK_LIST = list_of(lambda c, v, p: c.section(v, p, TASK), "tasks {id, position}", L.MAX_TASKS)
OBSTACLE_LIST = list_of(list_of(vector(2), "[x, y] vertices", L.MAX_OBSTACLE_VERTICES), "polygons",
                       L.MAX_OBSTACLES)


TOP = {
    "name": (ID, None),
    "origin": (lambda c, v, p: Origin(**c.section(v, p, ORIGIN)), None),
    "carrier": (lambda c, v, p: c.section(v, p, CARRIER), None),
    "carriers": (list_of(lambda c, v, p: c.section(v, p, TEAM), "carriers {id, sysid, position, ..., fleet}",
                       L.MAX_CARRIERS), None),
    "rovers": (lambda c, v, p: c.section(v, p, ROVERS), REQUIRED),
    "tasks": (lambda c, v, p: file_ref(c, v, p) if isinstance(v, dict) else TASK_LIST(c, v, p), REQUIRED),
    "obstacles": (lambda c, v, p: file_ref(c, v, p) if isinstance(v, dict) else OBSTACLE_LIST(c, v, p), []),
    "bounds": (list_of(vector(2), "two corners [[xmin, ymin], [xmax, ymax]]", 100), None),
    "collection": (lambda c, v, p: c.section(v, p, COLLECTION), None),
    "sim": (lambda c, v, p: c.section(v, p, SIM), {"speedup": 1.0, "faults": []}),
    "links": (lambda c, v, p: LinksConfig(**c.section(v, p, LINKS)), LinksConfig()),
    "planner": (lambda c, v, p: PlannerConfig(**c.section(v, p, PLANNER)), PlannerConfig()),
    "dwell": (number(ge=0, le=L.MAX_DWELL, unit="seconds on task"), 60.0),
    "operation": (boolean, False),
    "mqtt": (lambda c, v, p: c.section(v, p, MQTT), None),
    "geofence": (lambda c, v, p: c.section(v, p, GEOFENCE), None),
}



def fence_vertex(ctx: Ctx, v: Any, path: KeyPath) -> Any:
    if isinstance(v, dict):
        return ctx.section(v, path, {"lat": ORIGIN["lat"], "lon": ORIGIN["lon"]})
    if isinstance(v, list):
        return vector(2)(ctx, v, path)
    ctx.fail(path, f"expected a vertex [x, y] (ENU metres) or {{lat, lon}}, got {type_name(v)}")


GEOFENCE: dict[str, tuple[Parser, Any]] = {
    "polygon": (list_of(fence_vertex, "vertices [x, y] or {lat, lon}", L.MAX_OBSTACLE_VERTICES), None),
    "from": (one_of("bounds"), None),
    "alt_max": (number(gt=0, le=L.MAX_ALT, null=True, unit="metres above home"), None),
    "action": (one_of(*FENCE_ACTIONS), "report"),
}
