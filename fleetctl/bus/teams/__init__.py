"""One controller per team, coordinating over the MQTT bus (docs/mqtt.md#teams).

``protocol`` - the topics, the payloads and their validation; ``board`` - what one controller
knows of every team and task claim, and the hand-over rules (pure, no I/O); the asyncio side is
:mod:`fleetctl.run.teams.link`.
"""
