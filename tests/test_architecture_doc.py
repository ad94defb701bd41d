"""docs/architecture.md names only packages and modules that exist, and names every
package: the contributors' map moves with the code."""

from __future__ import annotations

import re

from tests.conftest import ROOT

DOC = ROOT / "docs" / "architecture.md"
_PATH = re.compile(r"`(cellrunner/[\w/]+(?:\.py)?)`")


def _named_paths(text: str) -> list[str]:
    return sorted(set(_PATH.findall(text)))


def test_every_module_and_package_the_page_names_exists():
    named = _named_paths(DOC.read_text())
    assert len(named) > 30, "the page names too few modules to be a map"
    missing = [p for p in named if not (ROOT / p).exists()]
    assert missing == []


def test_the_page_names_every_package():
    named = set(_named_paths(DOC.read_text()))
    packages = sorted(
        p.name
        for p in (ROOT / "cellrunner").iterdir()
        if (p / "__init__.py").exists() and p.name != "examples"
    )
    assert packages, "no packages found"
    assert [p for p in packages if f"cellrunner/{p}/" not in named] == []


def test_the_check_sees_a_module_that_is_not_there():
    text = "see `cellrunner/planning/no_such_module.py` and `cellrunner/model/`"
    named = _named_paths(text)
    assert named == ["cellrunner/model/", "cellrunner/planning/no_such_module.py"]
    assert [p for p in named if not (ROOT / p).exists()] == [
        "cellrunner/planning/no_such_module.py"
    ]
