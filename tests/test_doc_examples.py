"""The code blocks of README.md and docs/*.md run (issue 27, item 11).

Every fenced block is one test, run from a scratch directory where ``examples/`` and ``docs/``
are the repository's (so the paths in the docs work and the files they write land in the
scratch directory):

* ``python`` blocks are executed, the blocks of one file one after the other in one namespace
  (a later block may use an earlier one's names), ``__name__`` set to ``"__main__"``;
* ``bash``, ``sh`` and ``console`` blocks: every command line (``$ `` prompts in a console
  block, trailing ``# comments`` dropped) must be a ``flexkin`` command, run in-process by
  ``flexkin.cli.main`` with ``--quiet``, and must exit with status 0; the console blocks of
  docs/walkthrough.md are run and their output compared by tests/test_outputs_walkthrough.py;
* ``toml`` blocks must parse;
* blocks without a language (directory trees, sample output) are not code.

A block is marked on the line before its fence (blank lines between are allowed) with
``<!-- doc-test: skip: REASON -->`` (never run: it installs, starts a server, needs a cluster,
...) or ``<!-- doc-test: slow: REASON -->`` (run only with ``-m slow``).  The reason is shown
as the skip reason.
"""

from __future__ import annotations

import os
import re
import shlex
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
#: (file, language) pairs whose blocks another test runs and checks
CHECKED_ELSEWHERE = {("docs/walkthrough.md", "console"): "tests/test_outputs_walkthrough.py"}
_FENCE = re.compile(r"^```(\w*)\s*$")
_MARK = re.compile(r"<!--\s*doc-test:\s*(skip|slow)\s*:\s*(.*?)\s*-->")
_RUNS = ("python", "bash", "sh", "console", "toml")


@dataclass(frozen=True)
class Block:
    file: str          # relative to the repository
    line: int          # of the opening fence
    lang: str
    code: str
    mark: str          # "", "skip" or "slow"
    reason: str

    @property
    def id(self) -> str:
        return f"{self.file}:{self.line}:{self.lang}"


def doc_blocks(paths=DOCS) -> list[Block]:
    """Every fenced block of the given Markdown files, with its mark."""
    out = []
    for path in paths:
        lines = path.read_text(encoding="utf-8").splitlines()
        rel = path.relative_to(ROOT).as_posix()
        k = 0
        while k < len(lines):
            m = _FENCE.match(lines[k])
            if not m:
                k += 1
                continue
            start, lang = k, m.group(1).lower()
            k += 1
            body = []
            while k < len(lines) and not lines[k].startswith("```"):
                body.append(lines[k])
                k += 1
            k += 1
            j = start - 1
            while j >= 0 and not lines[j].strip():
                j -= 1
            mark = _MARK.search(lines[j]) if j >= 0 else None
            out.append(Block(rel, start + 1, lang, "\n".join(body) + "\n", mark.group(1) if mark else "",
                             mark.group(2) if mark else ""))
    return out


BLOCKS = [b for b in doc_blocks() if b.lang in _RUNS]


def _param(b: Block):
    marks = []
    elsewhere = CHECKED_ELSEWHERE.get((b.file, b.lang))
    if b.mark == "skip":
        marks.append(pytest.mark.skip(reason=f"doc-test: skip: {b.reason}"))
    elif elsewhere:
        marks.append(pytest.mark.skip(reason=f"run and checked by {elsewhere}"))
    elif b.mark == "slow":
        marks.append(pytest.mark.slow)
    return pytest.param(b, id=b.id, marks=marks)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    d = tmp_path_factory.mktemp("doc_examples")
    for name in ("examples", "docs"):
        os.symlink(ROOT / name, d / name)
    return d


_NAMESPACES: dict[str, dict] = {}


def _commands(b: Block) -> list[str]:
    cmds = []
    for ln in b.code.splitlines():
        s = ln.strip()
        if b.lang == "console":
            if not s.startswith("$ "):
                continue  # output
            s = s[2:]
        if not s or s.startswith("#"):
            continue
        cmds.append(s)
    return cmds


@pytest.mark.parametrize("block", [_param(b) for b in BLOCKS])
def test_doc_block_runs(block: Block, scratch, monkeypatch, capsys):
    monkeypatch.chdir(scratch)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    if block.lang == "toml":
        tomllib.loads(block.code)
        return
    if block.lang == "python":
        ns = _NAMESPACES.setdefault(block.file, {"__name__": "__main__"})
        exec(compile(block.code, f"{block.file}:{block.line}", "exec"), ns)
        return
    from flexkin.cli import main

    cmds = _commands(block)
    assert cmds, f"{block.id}: no command"
    for cmd in cmds:
        argv = shlex.split(cmd, comments=True)
        assert argv and argv[0] == "flexkin", (
            f"{block.id}: {cmd!r} is not a flexkin command: mark the block <!-- doc-test: skip: REASON -->")
        assert argv[1:2] != ["explore"], f"{block.id}: {cmd!r} serves until stopped: mark the block skip"
        quiet = ["--quiet"] if argv[1] in ("ik", "fk", "path", "workspace", "refine", "study", "reproduce") else []
        code = main(argv[1:] + quiet)
        _, err = capsys.readouterr()
        assert code == 0, (cmd, err)


def test_the_runner_sees_the_marks():
    """The marks are read, and every skipped block says why."""
    blocks = doc_blocks()
    assert len([b for b in blocks if b.lang == "python"]) >= 5
    assert all(b.reason for b in blocks if b.mark)
    assert {b.mark for b in blocks} >= {"", "skip"}
    assert any(b.file == "README.md" and b.lang == "python" and not b.mark for b in blocks)


# ---- what the docs claim, against the code (issue 27, item 11) --------------------------------
def _readme_result_claims() -> list[tuple[list[str], list[str], list[str]]]:
    """(result types, attributes claimed, attributes denied) of each statement of the README's
    "Every solver returns" paragraph: the first sentence of each of its bullets, or the
    paragraph itself (then about every result type)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("Every solver returns")
    para = text[start:text.index("\n\n", start)]
    tail = text[start + len(para):].lstrip("\n")
    bullets = re.split(r"\n- ", "\n" + tail.split("\n\n")[0])[1:] if tail.startswith("- ") else []
    out = []
    for stmt in (bullets or [para]):
        first = re.split(r"\.(?:\s|$)", " ".join(stmt.split()), maxsplit=1)[0]
        types = [t for t in re.findall(r"`([^`]+)`", first.partition(" no ")[0]) if t in RESULT_TYPES]
        first = re.sub(r"\([^)]*\)", "", first)                     # other parentheticals are asides
        pos, _, neg = first.partition(" no ")
        names = [re.sub(r"\(.*\)$", "", t) for t in re.findall(r"`([^`]+)`", pos)]
        attrs = [n for n in names if re.fullmatch(r"[a-z_]+", n)]
        denied = [re.sub(r"\(.*\)$", "", t) for t in re.findall(r"`([^`]+)`", neg)]
        out.append((types or list(SOLVER_RESULTS), attrs, denied))
    return out


def _result_types() -> dict:
    import flexkin
    from flexkin.analysis.feasibility import Feasibility
    from flexkin.cosserat.results import RefineResult

    return {"KinematicsResult": flexkin.KinematicsResult, "RodInverseResult": flexkin.RodInverseResult,
            "PathResult": flexkin.PathResult, "Workspace": flexkin.Workspace, "RefineResult": RefineResult,
            "Feasibility": Feasibility}


RESULT_TYPES = ("KinematicsResult", "RodInverseResult", "PathResult", "Workspace", "RefineResult", "Feasibility")
#: what the solvers return (check_feasibility is a check, not a solver)
SOLVER_RESULTS = RESULT_TYPES[:-1]


def test_readme_says_what_each_result_type_has():
    """Every attribute the README lists for a result type exists on it, and every one it says
    the type lacks does not."""
    import dataclasses

    classes = _result_types()

    def has(cls, name: str) -> bool:
        return name in {f.name for f in dataclasses.fields(cls)} or hasattr(cls, name)

    claims = _readme_result_claims()
    for types, attrs, denied in claims:
        for t in types:
            assert [a for a in attrs if not has(classes[t], a)] == [], (t, attrs)
            assert [a for a in denied if has(classes[t], a)] == [], (t, denied)
    assert len(claims) >= 4 and {t for types, _, _ in claims for t in types} >= set(SOLVER_RESULTS)


def test_one_figure_for_the_cost_of_feasibility_and_only_on_request(capsys, examples_dir):
    """README and docs/cli.md quote the same cost per solution, and say it is computed only
    when asked for; ``ik --json`` without ``--feasibility`` indeed has no feasibility."""
    import json

    from flexkin.cli import main

    costs = set()
    for name in ("README.md", "docs/cli.md"):
        text = " ".join((ROOT / name).read_text(encoding="utf-8").split())
        for sentence in re.split(r"(?<=[.;])\s", text):
            if "feasibility" in sentence.lower() or "feasible" in sentence.lower():
                costs |= {float(v) for v in re.findall(r"about (\d+(?:\.\d+)?) ms", sentence)}
        assert "computed although `--feasibility` was not asked" not in text
    assert len(costs) == 1, costs
    assert main(["ik", str(examples_dir / "unit_3rfr.toml"), "--pose", "0.05", "0.02", "20", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["solutions"] and all("feasible" not in s and "feasibility" not in s for s in d["solutions"])


def test_the_documented_numpy_reader_reads_a_shape_file(tmp_path, examples_dir):
    """docs/cli.md names the numpy call that reads a ``--shapes`` CSV: it must read one."""
    import numpy as np

    import flexkin
    from flexkin.io import write_shapes

    text = " ".join((ROOT / "docs" / "cli.md").read_text(encoding="utf-8").split())
    calls = re.findall(r"`numpy\.(loadtxt|genfromtxt)(\([^`]*\))?`", text)
    assert calls
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    f = str(tmp_path / "shapes.csv")
    write_shapes(f, flexkin.ik(mech, (0.05, 0.02, np.radians(20))))
    for fn, args in calls:
        call = f"np.{fn}{args or '(f)'}"
        a = eval(call, {"np": np, "f": f})
        assert a.shape[0] == 8 * 3 * 101 and a.shape[1] == 7, call
