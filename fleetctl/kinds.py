"""The kinds of journal records and operator events (``journal.jsonl`` ``kind``).

A module of its own, importing nothing of fleetctl, so that every layer that writes a journal
record (the run, the MQTT bus, the teams' link) names its kind through :class:`Ev`; the values are
the strings docs/records.md lists, so ``json.dumps`` writes them unchanged.
"""

from __future__ import annotations

from enum import StrEnum


class Ev(StrEnum):
    """Kinds of journal records and operator events (``journal.jsonl`` ``kind``)."""

    # records of the run itself
    RUN = "run"
    RESUMED = "resumed"
    SIM_STARTED = "sim_started"
    CONNECTED = "connected"
    MISSING = "missing"
    PHASE = "phase"
    SUMMARY = "summary"
    BUS = "bus"
    BUS_CONNECTED = "bus_connected"  # the bus's connection state (BusStatus) changed
    BUS_RECONNECTING = "bus_reconnecting"
    BUS_TELEMETRY_FAILED = "bus_telemetry_failed"  # the MQTT telemetry task stopped; the bus goes on
    BUS_FAILED = "bus_failed"  # the MQTT bus stopped for the rest of the run
    BUS_TASK_CHANGE = "bus_task_change"
    BUS_REJECTED = "bus_rejected"
    BUS_ERROR = "bus_error"
    WEB_FAILED = "web_failed"  # the web map (--web) could not listen; the run flies on without it
    # several teams (fleetctl.run.teams, docs/teams.md)
    TEAMS_PLAN = "teams_plan"  # how the tasks (or rovers to collect) were shared between the teams
    TEAM = "team"  # a team's run started or ended (its records: RUN/teams/<carrier>/<phase>/)
    HANDOVER = "handover"  # tasks handed from one team to another
    TEAM_SUMMARY = "team_summary"
    TEAM_CLAIM = "team_claim"
    TEAM_CLAIM_LOST = "team_claim_lost"
    TEAM_CLAIM_CONFLICT = "team_claim_conflict"
    TEAM_HANDOVER = "team_handover"
    TEAM_RELEASE = "team_release"
    TEAM_PEER = "team_peer"
    TEAM_MISMATCH = "team_mismatch"
    TEAM_MESSAGE_REJECTED = "team_message_rejected"
    TEAM_ALONE = "team_alone"
    # planning and commands
    PLAN = "plan"
    REPLAN = "replan"
    PLAN_BUDGET = "plan_budget"  # collection: one plan-and-check attempt's cost in mission s (batteries burn)
    COMMAND = "command"
    ACK = "ack"
    SPARES = "spares"
    LAUNCH = "launch"  # write-ahead: a rover is about to be armed for a task
    ROVER_STATE = "rover_state"
    # carrier
    CARRIER_STARTED = "carrier_started"
    STOP_REACHED = "stop_reached"
    CARRIER_RELEASED = "carrier_released"
    CARRIER_OFF_STOP = "carrier_off_stop"  # collection: the carrier is not parked at its stop; rovers hover
    CARRIER_PARKED = "carrier_parked"  # collection complete: the carrier in HOLD and disarmed
    ETA = "eta"  # the live makespan prediction at a stop (mission s of the phase)
    CARRIER_LOST = "carrier_lost"
    CARRIER_BACK = "carrier_back"
    HOLD = "hold"
    # rovers and tasks
    ROVER_LAUNCHED = "rover_launched"
    ROVER_REFUSED = "rover_refused"
    ROVER_FAILED = "rover_failed"
    ROVER_SKIPPED = "rover_skipped"
    ROVER_UNUSABLE = "rover_unusable"
    ROVER_REJOINED = "rover_rejoined"
    ROVER_RELEASED = "rover_released"
    ROVER_LANDING = "rover_landing"
    ROVER_LOADED = "rover_loaded"
    ROVER_UNREACHABLE = "rover_unreachable"
    ROVER_LET_GO = "rover_let_go"  # collection: it cannot arrive (battery empty, failsafe, down short): left
    TASK_REACHED = "task_reached"
    TASK_RETURNED = "task_returned"
    TASK_TIMEOUT = "task_timeout"
    TASK_UNSERVED = "task_unserved"
    REASSIGN_PENDING = "reassign_pending"  # a flying rover is lost: its task waits links.reassign_after
    TASKS_CHANGED = "tasks_changed"
    TASK_CHANGE_REJECTED = "task_change_rejected"
    COLLECTION_STARTED = "collection_started"
    NOTHING_TO_COLLECT = "nothing_to_collect"
    # a long operation (fleetctl.run.operation, docs/operations.md)
    SORTIE_LAUNCHED = "sortie_launched"  # a rover left the deck for a sortie (its tasks)
    TASK_STARTED = "task_started"  # a rover is at its task: the work starts
    TASK_DONE = "task_done"  # the firmware reported the task's duration of work done
    SORTIE_CONTINUED = "sortie_continued"  # the rest of a sortie started after work timed on the ground
    SORTIE_RETURNING = "sortie_returning"  # a rover left its last task for its pick-up stop
    SORTIE_BACK = "sortie_back"  # a rover of a sortie is loaded on the deck
    SORTIE_LOST = "sortie_lost"  # a rover was lost during its sortie (its work left is replanned)
    SORTIE_CALLED_BACK = "sortie_called_back"  # a replan called a rover in the air back early (tasks dropped)
    BATTERY_SWAPPED = "battery_swapped"  # a rover's battery swapped on the deck, back to full
    OPERATION_DONE = "operation_done"  # every task worked, every rover back (or the operation ended short)
    # supervision
    LINK_LOST = "link_lost"
    LINK_BACK = "link_back"
    BATTERY_LOW = "battery_low"
    OFF_COURSE = "off_course"
    STATUSTEXT = "statustext"
    ARMED = "armed"  # a vehicle's heartbeat shows it armed
    DISARMED = "disarmed"
    MODE = "mode"  # a vehicle's flight mode changed
    LANDED_STATE = "landed_state"  # a vehicle's EXTENDED_SYS_STATE landed state changed
    ROUTE_CONFLICT = "route_conflict"
    # field safety (docs/field-safety.md)
    PREFLIGHT_FAILED = "preflight_failed"  # a rover left out of the run
    PREFLIGHT_WARNING = "preflight_warning"
    FAILSAFE = "failsafe"  # what a vehicle does on link loss
    FAILSAFE_SET = "failsafe_set"  # links.failsafe set it
    FAILSAFE_WARNING = "failsafe_warning"  # rovers with RTL on link loss
    GEOFENCE = "geofence"  # uploaded
    GEOFENCE_WARNING = "geofence_warning"
    GEOFENCE_BREACH = "geofence_breach"
    FIRMWARE_SPEEDS = "firmware_speeds"  # the mission's speeds written to an autopilot (docs/autopilots.md)
    # the end of a phase or run
    DEPLOYED = "deployed"
    DEPLOY_INCOMPLETE = "deploy_incomplete"
    DWELL = "dwell"
    COLLECTED = "collected"
    ERROR = "error"
    INTERRUPTED = "interrupted"


__all__ = ["Ev"]
