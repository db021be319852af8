"""fleetctl: mission controller for a marsupial drone team (carrier + UAV rovers) over MAVLink."""
