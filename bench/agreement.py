"""Does ``check`` agree with the twin, and both with the truth, on cells nobody wrote?

Run: ``python bench/agreement.py --cells N --seed S [--jobs J] [--out DIR] [--kinds K,...]`` from the
repository root. It generates N jobs (``bench/cellgen.py``: feasible by construction, or
broken in one known way), runs ``check`` on each and, where ``check`` approves, ``dry-run``
on the twin, and classifies each job:

- **true accept**: feasible, approved, the twin ends 0;
- **true refuse**: broken, refused;
- **false approval**: approved, and the twin fails it (check should have refused);
- **twin false OK**: broken, approved, and the twin reports 0 (both missed the defect);
- **false refusal**: feasible by construction (a witness configuration exists), refused.

It prints a table (kinds x classes) and the targets of issue 33 (0 false approvals, 0
twin false OK, at most 1% false refusals), and writes each disagreement's cell and task
file under ``--out`` (default ``var/agreement``) with the command that replays it.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.cellgen import FEASIBLE, KINDS, Case, corpus_seeds

CLASSES = ("true accept", "true refuse", "false approval", "twin false OK", "false refusal")
#: a check that ended in an internal error exits 1 as a refusal does: it is a bug, never a
#: refusal (a mesh wall named in contact: crashed check, and counted as a true refuse)
CRASHED = "check crashed"
DISAGREEMENTS = ("false approval", "twin false OK", "false refusal", CRASHED)
#: verdicts that are the generator's or the bench's fault, not check's or the twin's
BENCH_FAULTS = ("invalid file", "twin did not run", "no witness")


@dataclass(frozen=True)
class Verdict:
    """What check and the twin said of one generated job, and its class."""

    name: str
    kind: str
    check_code: int
    result_code: int | None  # the twin's, where check approved
    verdict: str
    message: str
    check_s: float
    folder: str
    rehearse: str = ""  # what dry-run was given besides the files (a fault it injected)


def cli(*argv: str) -> tuple[int, dict]:
    """One cellrunner command in this process with --json, as a user runs it: its exit
    code and object (a command refused before it printed one: its error lines as the
    object's errors). The tests' rig for the spec-written cells runs commands with it."""
    from cellrunner.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([*argv, "--json"])
        except SystemExit as leave:
            code = leave.code if isinstance(leave.code, int) else 2
    text = out.getvalue().strip()
    return code, (
        json.loads(text) if text else {"ok": False, "errors": err.getvalue().splitlines()}
    )


def classify(
    feasible: bool,
    check_code: int,
    result_code: int | None,
    expect_code: int = 0,
    recovered: bool = True,
) -> str:
    """The class of a job from its truth, check's exit code and the twin's result code
    (``expect_code`` where the rehearsal injects a fault; ``recovered``: its on_error
    was done)."""
    if check_code == 2:
        return "invalid file"  # the generator wrote a file the loader refuses: its bug
    if check_code != 0:
        return "false refusal" if feasible else "true refuse"
    if result_code is None:
        return "twin did not run"  # the rehearsal ended without a result: the bench's fault
    if result_code != expect_code or not recovered:
        return "false approval"
    return "true accept" if feasible else "twin false OK"


def judge(case: Case, out: Path) -> Verdict:
    """Write ``case`` under ``out``, run check and (if approved) dry-run, classify."""
    folder = out / case.name
    cell, task = case.write(folder)
    t0 = time.perf_counter()
    check_code, checked = cli("check", str(cell), str(task))
    check_s = time.perf_counter() - t0
    result_code, message = None, "; ".join(checked.get("errors", []))[:300]
    if check_code == 0:
        _, rehearsed = cli("dry-run", str(cell), str(task), *case.rehearse)
        result_code = rehearsed.get("result_code")
        message = str(rehearsed.get("result_text") or "; ".join(rehearsed.get("errors", [])))[:300]
    recovered = not case.expect_code or "on_error done" in message
    verdict = classify(case.feasible, check_code, result_code, case.expect_code, recovered)
    if check_code == 1 and any(": internal error: " in e for e in checked.get("errors", [])):
        verdict = CRASHED
    return Verdict(
        case.name,
        case.kind,
        check_code,
        result_code,
        verdict,
        message,
        check_s,
        str(folder),
        "".join(f" {arg}" for arg in case.rehearse),
    )


def _judge_one(args: tuple[int, str, str]) -> Verdict:
    from bench.cellgen import generate

    seed, kind, out = args
    try:
        case = generate(seed, kind)
    except RuntimeError as exc:  # no witnesses found: the generator's, not check's
        return Verdict(f"s{seed}-{kind}", kind, -1, None, "no witness", str(exc), 0.0, "")
    return judge(case, Path(out))


def run(
    count: int,
    seed: int,
    jobs: int,
    out: Path,
    kinds: tuple[str, ...] = KINDS,
    progress: bool = False,
    resume: bool = False,
) -> list[Verdict]:
    """Judge ``count`` generated jobs of ``kinds`` from ``seed`` on ``jobs`` processes: the
    kinds in turn, each job on its own seed (``corpus_seeds``). Each verdict is appended to
    ``out/verdicts.jsonl`` as it comes, so a long run's findings can be read before it ends
    and are kept if it is stopped; ``resume`` keeps the verdicts already there and judges
    only the jobs they miss; ``progress`` prints a line per job on stderr."""
    from cellrunner.sim.mujoco_loader import enable_pictures

    enable_pictures()  # before any job imports MuJoCo: the align cameras draw pictures
    cases = [(s, kind, str(out)) for s, kind in corpus_seeds(count, seed, kinds)]
    out.mkdir(parents=True, exist_ok=True)
    verdicts: list[Verdict] = []
    path = out / "verdicts.jsonl"
    if resume and path.exists():
        verdicts = [Verdict(**json.loads(line)) for line in path.read_text().splitlines() if line]
        done = {v.name.split("-")[0] for v in verdicts}
        cases = [c for c in cases if f"s{c[0]}" not in done]
    with path.open("a" if resume else "w") as log:

        def keep(verdict: Verdict) -> None:
            verdicts.append(verdict)
            log.write(json.dumps(asdict(verdict)) + "\n")
            log.flush()
            if progress:
                print(
                    f"[{len(verdicts)}/{count}] {verdict.name}: {verdict.verdict}"
                    f" (check {verdict.check_s:.2f} s)",
                    file=sys.stderr,
                    flush=True,
                )

        if jobs <= 1:
            for case in cases:
                keep(_judge_one(case))
        else:
            with ProcessPoolExecutor(max_workers=jobs) as pool:
                for verdict in pool.map(_judge_one, cases):
                    keep(verdict)
    return verdicts


def table(verdicts: list[Verdict]) -> str:
    """Kinds x classes, counts, and the targets."""
    counts = Counter((v.kind, v.verdict) for v in verdicts)
    width = max(len(k) for k in KINDS)
    lines = [f"{'kind':<{width}}  " + "  ".join(f"{c:>14}" for c in CLASSES)]
    for kind in [k for k in KINDS if any(v.kind == k for v in verdicts)]:
        lines.append(f"{kind:<{width}}  " + "  ".join(f"{counts[(kind, c)]:>14}" for c in CLASSES))
    total = Counter(v.verdict for v in verdicts)
    lines.append(f"{'all':<{width}}  " + "  ".join(f"{total[c]:>14}" for c in CLASSES))
    feasible = sum(1 for v in verdicts if v.kind in FEASIBLE)
    rate = total["false refusal"] / feasible if feasible else 0.0
    check_s = sorted(v.check_s for v in verdicts)
    p95 = check_s[min(len(check_s) - 1, int(0.95 * len(check_s)))] if check_s else 0.0
    lines.append(
        f"targets: false approvals {total['false approval']} (0), twin false OK "
        f"{total['twin false OK']} (0), false refusals {rate:.1%} (<= 1%), "
        f"cold check p95 {p95:.2f} s (<= 2 s)"
    )
    if total[CRASHED]:
        lines.append(f"check crashed (internal errors, not refusals): {total[CRASHED]}")
    if total["invalid file"]:
        lines.append(f"generator bugs: {total['invalid file']} files the loader refused")
    if total["no witness"]:
        lines.append(f"seeds the generator found no witnesses for: {total['no witness']}")
    if total["twin did not run"]:
        lines.append(f"rehearsals that gave no result: {total['twin did not run']}")
    return "\n".join(lines)


def write_disagreements(verdicts: list[Verdict], out: Path) -> Path:
    """A list of each disagreement with the commands that replay it."""
    path = out / "disagreements.txt"
    rows = [v for v in verdicts if v.verdict in (*DISAGREEMENTS, *BENCH_FAULTS)]
    text = "".join(
        f"{v.verdict}: {v.name}: {v.message}\n"
        f"  cellrunner check {v.folder}/cell.yaml {v.folder}/task.yaml\n"
        f"  cellrunner dry-run {v.folder}/cell.yaml {v.folder}/task.yaml{v.rehearse}\n"
        for v in rows
    )
    path.write_text(text or "none\n")
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=60, help="generated jobs (default 60)")
    parser.add_argument("--seed", type=int, default=1, help="first seed (default 1)")
    parser.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--out", type=Path, default=Path("var/agreement"))
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("--progress", action="store_true", help="a line per job on stderr")
    parser.add_argument(
        "--resume", action="store_true", help="keep OUT's verdicts, judge the jobs they miss"
    )
    parser.add_argument(
        "--kinds", default=",".join(KINDS), help="comma-separated kinds (default: all)"
    )
    args = parser.parse_args(argv)
    kinds = tuple(k for k in args.kinds.split(",") if k)
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        parser.error(f"unknown kinds {', '.join(unknown)}; known: {', '.join(KINDS)}")
    verdicts = run(args.cells, args.seed, args.jobs, args.out, kinds, args.progress, args.resume)
    listing = write_disagreements(verdicts, args.out)
    if args.json:
        print(json.dumps([asdict(v) for v in verdicts], indent=1))
    else:
        print(table(verdicts))
        print(f"disagreements and how to replay them: {listing}")
    bad = sum(1 for v in verdicts if v.verdict in (*DISAGREEMENTS, *BENCH_FAULTS))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
