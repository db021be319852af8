"""Several carriers on one mission (issue 17): share the tasks (deployment) or the rovers
(collection) between teams, each team planned by today's planners; the nearest-carrier baseline
and a lower bound. Pure maths, no I/O.
"""

from planners.teams.allocation import plan_teams, plan_teams_nearest
from planners.teams.bounds import teams_lower_bound
from planners.teams.plan import TeamPlan, TeamsPlan
from planners.teams.problem import TeamsProblem

__all__ = ["TeamPlan", "TeamsPlan", "TeamsProblem", "plan_teams", "plan_teams_nearest", "teams_lower_bound"]
