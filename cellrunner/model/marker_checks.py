"""Located checks of the cell's ``markers:`` (SPEC section 13): each printed on its
part's or fixture's surface, and each (dictionary, id) printed once in the cell, so a
camera that finds it knows what it found."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cellrunner.model.cell import Fixture, Part
    from cellrunner.model.loaded import LoadedCell
    from cellrunner.model.report import Report


def check_markers(loaded: LoadedCell, report: Report) -> None:
    """Every marker of a part or fixture lies on its surface; no (dictionary, id) twice."""
    cell = loaded.cell
    if not any(p.markers for p in cell.parts) and not any(f.markers for f in cell.fixtures):
        return
    from cellrunner.model.marker_surface import off_surface

    seen: dict[tuple[str, int], str] = {}
    owners: list[tuple[str, int, str, str, Part | Fixture]] = [
        ("parts", i, "part", p.name, p) for i, p in enumerate(cell.parts)
    ]
    owners += [("fixtures", i, "fixture", f.name, f) for i, f in enumerate(cell.fixtures)]
    for section, i, kind, name, owner in owners:
        if not owner.markers:
            continue
        shape = owner.to_shape(loaded.resolve)
        for j, marker in enumerate(owner.markers):
            path = (section, i, "markers", j)
            key = (marker.dictionary, marker.id)
            if key in seen:
                report.error(
                    path + ("id",),
                    f"marker {marker.id} ({marker.dictionary}) is printed twice: also on "
                    f"{seen[key]}; a camera could not tell them apart",
                )
            seen[key] = f"{kind} {name!r}"
            problem = off_surface(shape, marker.pose.matrix(), float(marker.size))
            if problem is not None:
                report.error(
                    path + ("pose",),
                    f"marker {marker.id} is off the surface of {kind} {name!r}: {problem} "
                    f"(pose is in the {kind}'s own frame, at its centre; a marker lies on a "
                    "face with Z out of it)",
                )
