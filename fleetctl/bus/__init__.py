"""The MQTT fleet bus (:mod:`.client`) and its settings (:mod:`.config`)."""
