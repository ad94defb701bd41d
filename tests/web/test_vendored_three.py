"""The three.js files the status page's 3D view loads are the pinned release's, byte for
byte (scripts/vendor-three copies them from npm and writes the sums checked here)."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from tests.conftest import ROOT

STATIC = ROOT / "cellrunner" / "web" / "static" / "three"

#: the release scripts/vendor-three pins, and the sha256 of each file it copies from it
PINNED = "0.187.0"
SHA256 = {
    "LICENSE": "8b378ebe60e2fe500158cb0ac71cb5e8b7d92953c2abcc63a0eb90499653b5bc",
    "OrbitControls.js": "e7fca2fe9e7670a828af9b28084669a5909445b7f36f1f26cee9bf8f2961c32c",
    "three.core.js": "613e370f76638fdef83926642bf256dc9615684922de1ce1f63a8583e5d78578",
    "three.module.js": "104f56145899722094556490d787aae0617cc2fc3382f31df02d724ea1aee341",
}


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_vendored_files_are_the_pinned_release():
    assert (STATIC / "VERSION").read_text().strip() == PINNED
    assert {name: sha256(STATIC / name) for name in SHA256} == SHA256


def test_the_script_pins_the_same_release_and_the_sums_file_agrees():
    script = (ROOT / "scripts" / "vendor-three").read_text()
    assert re.search(rf"^VERSION={re.escape(PINNED)}$", script, re.M)
    listed = dict(
        reversed(line.split()) for line in (STATIC / "SHA256SUMS").read_text().splitlines()
    )
    assert {k: v for k, v in listed.items() if k != "VERSION"} == SHA256


def test_the_module_says_its_revision_and_the_licence_is_mit():
    revision = PINNED.split(".")[1]
    assert f"const REVISION = '{revision}'" in (STATIC / "three.core.js").read_text()
    assert (STATIC / "LICENSE").read_text().startswith("The MIT License")
