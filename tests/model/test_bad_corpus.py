"""Every file under tests/data/bad/ must be refused with the diagnostic its first line
names (``# expect: LINE:COL: TEXT``; ``*`` for any position), exit code 2, one line per
error, and no traceback."""

from __future__ import annotations

import re

import pytest

from cellrunner.cli.main import main
from tests.conftest import DEMO_CELL, ROOT

BAD = sorted((ROOT / "tests" / "data" / "bad").glob("*.yaml"))


def test_corpus_is_large_enough():
    assert len(BAD) >= 30


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.name)
def test_bad_file_is_located(path, in_repo, capsys):
    expect = re.match(r"# expect: (\*|\d+:\d+): (.*)$", path.read_text().splitlines()[0])
    assert expect, f"{path.name}: first line must be '# expect: LINE:COL: TEXT'"
    where, text = expect.groups()
    rel = path.relative_to(ROOT)
    argv = (
        ["validate", str(rel)]
        if path.name.startswith("cell_")
        else ["validate", str(DEMO_CELL.relative_to(ROOT)), str(rel)]
    )
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if ": error: " in line]
    assert lines, err
    for line in lines:  # every error line is FILE:LINE:COL: error: MESSAGE
        assert re.match(r"^[^:]+:\d+:\d+: error: \S", line), line
    prefix = f"{rel}:{where}: error: " if where != "*" else f"{rel}:"
    assert any(line.startswith(prefix) and text in line for line in lines), (
        f"expected {prefix}...{text}\ngot:\n{err}"
    )
