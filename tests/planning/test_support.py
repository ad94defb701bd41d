"""A placed part must rest on something (issue 24: check approved a place in thin air,
off the pallet, which the twin then failed as the part fell)."""

from __future__ import annotations

from tests.conftest import DEMO_CELL
from tests.rig import json_of

PLACE = "task: t\nsteps:\n  - move: home\n  - pick: {at: infeed}\n  - place: {at: pallet, offset: [0, 0, DZ]}\n  - move: home\n"


def test_a_place_in_thin_air_is_refused(tmp_path):
    """The pallet frame's Z points down: -0.02 lets the block go 23 mm above the table."""
    task = tmp_path / "t.yaml"
    task.write_text(PLACE.replace("DZ", "-0.02"))
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert out["errors"] == [
        "step 8 release 'pallet': the part 'block' would be let go with nothing under it "
        "within place_tolerance 5 mm (the nearest thing is fixture 'table', 23.0 mm away): "
        "it falls; fix: lower the place frame onto its support, or place it where a fixture "
        "or an earlier part holds it"
    ]


def test_a_drop_within_the_place_tolerance_is_a_place(tmp_path):
    task = tmp_path / "t.yaml"
    task.write_text(PLACE.replace("DZ", "-0.001"))  # 4 mm above the table
    assert json_of("check", str(DEMO_CELL), str(task), "--no-cache")["ok"]


def test_an_upper_layer_rests_on_the_slot_below(tmp_path):
    """The palletizer's slot 4 (layer 2) is let go over slot 0's carton, which an earlier
    job put there: it rests on it."""
    out = json_of("check", "cells/palletizer_ur10e.yaml", "tasks/palletize.yaml", "-p", "slot=4")
    assert out["ok"], out["errors"]


def test_check_forgives_the_drop_the_twin_forgives():
    """check lets a part fall as far as the twin lands it where it was put (the SPEC's own
    example lets its block go 10 mm above the table)."""
    from cellrunner.planning.support import FORGIVEN_DROP_M
    from cellrunner.sim.places import PLACE_DROP_M

    assert FORGIVEN_DROP_M == PLACE_DROP_M


def test_the_nearest_thing_named_is_the_carton_below_not_the_pallet(tmp_path):
    """Slot 4 (layer 2) let go 20 mm above slot 0's carton: the message names that carton
    (an earlier slot's), not the pallet far under it (issue 33)."""
    from pathlib import Path

    task = tmp_path / "palletize.yaml"
    text = Path("tasks/palletize.yaml").read_text()
    task.write_text(text.replace("[0.22, 0.17, 0.10]", "[0.22, 0.17, 0.12]"))
    out = json_of("check", "cells/palletizer_ur10e.yaml", str(task), "-p", "slot=4")
    error = out["errors"][0]  # and one per slot of the upper layers after it
    assert error.startswith("step 9 release 'pallet_slot0[slot=4]': the part 'carton' "), error
    assert (
        "(the nearest thing is the part 'carton' an earlier slot put down, 20.0 mm away)" in error
    )
