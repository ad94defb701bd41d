"""A refused plan's typed failure, as the journal tests write and read it back."""

from __future__ import annotations

from cellrunner.model.body import Body, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind

REFUSAL = Failure(
    FailureKind.COLLISION,
    "every IK branch meets something",
    ("branch 1: fixture 'table'",),
    (
        Blocker(Body(BodyKind.FIXTURE, "table"), -0.004, 3),
        Blocker(Body(BodyKind.ROBOT_LINK, "wrist_3")),
    ),
    "fix: raise the approach by 30 mm",
    3,
    "step 3 approach 'pick'",
)
