"""The mission's embedded simulated fleet for the block of a command that does not fly
(``status``, ``sim``, ``keys provision``)."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING

from fleetctl.cli.errors import CliError, check_speedup
from fleetctl.mission import Mission
from fleetctl.run.context import ExecutionError
from fleetctl.run.sim import embedded_fleet as run_embedded_fleet

if TYPE_CHECKING:
    from sitl import SimFleet


@contextlib.asynccontextmanager
async def embedded_fleet(mission: Mission, *, speedup: float | None = None, signing_from_env: bool = True,
                         always: bool = False) -> AsyncIterator[SimFleet | None]:
    """The mission's embedded simulated fleet for the block (None on real links), as every flying
    command starts it (:func:`fleetctl.run.sim.embedded_fleet`: every carrier and rover of every
    team); an error starting it as a :class:`CliError`."""
    check_speedup(speedup)
    fleet = run_embedded_fleet(mission, speedup=speedup, signing_from_env=signing_from_env, always=always)
    try:
        sim = await fleet.__aenter__()
    except ExecutionError as e:
        raise CliError(str(e)) from None
    try:
        yield sim
    finally:
        await fleet.__aexit__(None, None, None)
