"""Which link-loss failsafe earns a rover the RTL warning (fleetctl.run.safety.rtl_on_link_loss):
the one predicate that ``fleetctl status`` and a flying command's admission both use."""

from __future__ import annotations

import pytest

from fleetctl.run.safety import PreflightFailsafe, rtl_on_link_loss


@pytest.mark.parametrize(("action", "warned"), [("rtl", True), ("RTL", True), ("continue, then rtl", True),
                                                ("hold", False), ("land", False), ("none", False),
                                                (None, False)])
def test_a_return_to_launch_is_warned_of(action: str | None, warned: bool) -> None:
    assert rtl_on_link_loss(PreflightFailsafe({}, action, f"link loss: {action}")) is warned
