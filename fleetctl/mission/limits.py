"""Physical and size limits of a mission file: every bound the loader enforces, in one place.

``docs/mission-limits.md`` explains each number. The aim: whatever the loader accepts, the
planners plan in bounded time and memory and every time in the plan is a finite number. A value
outside a limit is refused with a message naming its key, the limit and what to change.
"""

from __future__ import annotations

# --------------------------------------------------------------------------- the file and its YAML
MAX_FILE_BYTES = 512 * 1024  # a mission file (the largest shipped one is ~4 KB)
MAX_YAML_DEPTH = 32  # nesting of mappings/lists (a mission needs 5)
MAX_YAML_NODES = 100_000  # scalars + lists + mappings after alias expansion
MAX_ALIASES = 100  # uses of '*anchor' in one file
MAX_STRING = 256  # characters of an id, name or other string value
MAX_NUMBER_DIGITS = 40  # characters of a number as written (more cannot be a physical value)

# --------------------------------------------------------------------------- tasks/obstacles {file: PATH}
MAX_DATA_FILE_BYTES = 2 * 1024 * 1024  # a .plan/.geojson/.kml/.csv (5000 vertices as GeoJSON ~ 250 KB)
MAX_DATA_FILE_ENTRIES = 10_000  # features, mission items, placemarks or rows looked at in one file

# --------------------------------------------------------------------------- list lengths
MAX_TASKS = 1000  # one team flies at most MAX_ROVERS: more tasks need several carriers or an operation
MAX_ROVERS = 254  # MAVLink system ids 1..255 of one link: one carrier + 254 rovers
MAX_CARRIERS = 16  # teams of one mission (carriers:)
MAX_OBSTACLES = 500
MAX_OBSTACLE_VERTICES = 200  # per polygon
MAX_TOTAL_VERTICES = 5000  # all polygons together
MAX_FAULTS = 100

# --------------------------------------------------------------------------- physical values
MAX_COORD = 100_000.0  # m: |x|, |y| of any ENU position or bounds corner (a 200 km square)
MAX_HEIGHT = 10_000.0  # m: a task's height above ground
MAX_ALT = 20_000.0  # m above the WGS84 ellipsoid (origin and lat/lon tasks); min is MIN_ALT
MIN_ALT = -1_000.0
MAX_HEADING = 3600.0  # compass degrees, |heading_deg| (ten turns: anything sane)
MIN_SPEED = 0.01  # m/s: slower cannot fly; keeps every flight time finite
MAX_SPEED = 150.0  # m/s (540 km/h) for carrier and rovers
MIN_ACCEL = 0.01  # m/s²
MAX_ACCEL = 200.0  # m/s² (~20 g)
MIN_TURN_RATE = 0.001  # rad/s
MAX_TURN_RATE = 100.0  # rad/s
MAX_DECK_HEIGHT = 10.0  # m: |carrier.deck_height| (the deck above or below the carrier's reported position)
MAX_HANDLING_TIME = 3600.0  # s: unload_time, load_time, rovers.takeoff_time, rovers.land_time
MAX_DWELL = 7 * 86_400.0  # s on task (a week)
MIN_RANGE = 0.01  # m: deploy_range, endurance_range, collection range
MAX_RANGE = 1_000_000.0  # m (1000 km): more than any battery flies
MAX_ENERGY = 1e9  # energy.initial / energy.task in the file's energy unit
MAX_RHO = 1e9  # energy.rho, metres per unit of energy
MAX_SPEEDUP = 1000.0  # simulated seconds per wall second
MIN_SPEEDUP = 0.01
MAX_SIM_TIME = 1e7  # s: fault at/until (~116 days)
MAX_LATENCY = 60.0  # s: a latency fault
MAX_DRAIN = 1000.0  # battery drain multiplier
MAX_DRIFT = 10.0  # m a simulated landing drifts (sim fault land_drift)
MAX_HEARTBEAT_TIMEOUT = 3600.0  # s
MIN_HEARTBEAT_TIMEOUT = 0.01
MAX_SEED = 2**32 - 1
MAX_BUDGET_MS = 600_000.0  # planner.budget_ms: ten minutes of improvement search

# --------------------------------------------------------------------------- the roadmap (planner lee-graph)
MAX_XI = 1000.0  # ξ₁, ξ₃ (nodes per metre of √area); ξ₂, ξ₄ (nodes)
MAX_ROADMAP_NODES = 1500  # ℵ₁ = √(w·h)·ξ₁ + ξ₂ and ℵ_add = √(w·h)·ξ₃ + ξ₄ (eq. 6.5, 6.7)
# expected edges of the global PRM: ℵ₁²/2 · min(1, π·δ²/(w·h)), δ = max(d_deploy, (w+h)/2·φ)
MAX_ROADMAP_EDGES = 100_000  # (the planner itself refuses more than 120,000 actual edges)

# --------------------------------------------------------------------------- task changes (MQTT, live edits)
# A task added over MQTT is refused (unless the message says "force": true) when it lies
# outside ``bounds`` or, without bounds, farther than FAR_FACTOR x the mission's extent (the
# largest distance between the carrier start and any task, at least MIN_EXTENT) from every
# current task and from the carrier start. Removing every task is refused the same way.
FAR_FACTOR = 2.0
MIN_EXTENT = 100.0  # m

# --------------------------------------------------------------------------- warnings (mission/outliers.py)
# ``plan`` and ``deploy`` warn about a task farther from the centroid of the other tasks than
# OUTLIER_FACTOR x their median distance from it and than OUTLIER_MIN_DISTANCE.
OUTLIER_FACTOR = 3.0
OUTLIER_MIN_DISTANCE = 200.0  # m

__all__ = [name for name in dir() if name.isupper()]
