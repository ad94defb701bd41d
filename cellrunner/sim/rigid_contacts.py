"""How rigid the twin's fixtures are in contact (issue 33).

MuJoCo's contacts are soft: a constraint's reference acceleration is mass-normalised, so
the force that resists an overlap scales with the effective mass of what presses. A pin of
0.1 kg held over the rim of a hole sank 0.85 mm into the rim under MuJoCo's default
contact (time constant 20 ms, impedance 0.9-0.95 over 1 mm) before the guarded insert
felt its force limit, and popped into the hole: the twin reported a jam as a good insert.

The fixtures a task names in a step's ``contact:`` (the walls of a hole, a nest: what a
part is meant to slide along and must not sink into) are built rigid: their contacts take the stiffest time constant the step
allows (2 physics steps, critically damped) and reach their full impedance within
:data:`IMPEDANCE_WIDTH_M` of overlap, and a fixture's parameters win over those of what
touches it (``solmix``), so a light pin meets the same rigid wall as a heavy carton.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

#: the overlap (m) over which a fixture's contact reaches its full impedance
IMPEDANCE_WIDTH_M = 2e-4
#: the impedance at no overlap and at IMPEDANCE_WIDTH_M (MuJoCo's d0, dwidth)
IMPEDANCE = (0.99, 0.999)
#: a fixture's weight when MuJoCo mixes the parameters of two contacting geoms
FIXTURE_SOLMIX = 1000.0


def rigid_contact_attrs(timestep_s: float) -> dict[str, str]:
    """The MJCF contact attributes of a fixture's geom for physics steps of ``timestep_s``."""
    d0, dwidth = IMPEDANCE
    return {
        "solref": f"{2 * timestep_s:.6g} 1",
        "solimp": f"{d0:g} {dwidth:g} {IMPEDANCE_WIDTH_M:g}",
        "solmix": f"{FIXTURE_SOLMIX:g}",
    }


def contact_fixtures(tasks: Iterable[Any]) -> frozenset[str]:
    """The fixtures named in ``contact:`` by any step of ``tasks`` (loaded tasks)."""
    return frozenset(
        name
        for task in tasks
        for spec in task.steps
        for name in getattr(spec.args, "contact", None) or ()
    )
