"""Mission files: the typed model (:mod:`.model`) and the YAML loader that validates every key
(:mod:`.loader`)."""

from fleetctl.mission.loader import load_mission, parse_mission
from fleetctl.mission.model import (
    FAULT_KINDS,
    CarrierConfig,
    EnergyConfig,
    Fault,
    LinksConfig,
    Mission,
    MissionError,
    MqttConfig,
    PlannerConfig,
    RoadmapConfig,
    RoversConfig,
    RoverUnit,
    SigningConfig,
    SimConfig,
    TlsConfig,
)

__all__ = [
    "CarrierConfig",
    "EnergyConfig",
    "FAULT_KINDS",
    "Fault",
    "LinksConfig",
    "Mission",
    "MissionError",
    "MqttConfig",
    "PlannerConfig",
    "RoadmapConfig",
    "RoverUnit",
    "RoversConfig",
    "SigningConfig",
    "SimConfig",
    "TlsConfig",
    "load_mission",
    "parse_mission",
]
