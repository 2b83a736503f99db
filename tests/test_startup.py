"""What a command loads (issue 26): an IK or FK call imports no scipy.integrate, scipy.optimize,
scipy.sparse or scipy.special, no Cosserat code and no plotting.

Each command runs as ``flexkin.cli.main`` in a fresh interpreter, like the console script, after
one warm-up run of the same command (which writes the on-disk caches a first run in a new
cache directory builds: compiled kernels, the pinned atlas).  A last test shows that the check
can fail: the Cosserat refinement does import flexkin.cosserat.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROTO = str(ROOT / "examples" / "prototype_3pfr.toml")

CHILD = """
import contextlib, io, json, sys
from flexkin.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    rc = main(sys.argv[2:])
with open(sys.argv[1], "w") as f:
    json.dump({"rc": rc, "modules": sorted(sys.modules)}, f)
"""

#: never imported by an IK or FK command
FORBIDDEN = ("scipy.integrate", "scipy.optimize", "scipy.sparse", "scipy.special", "flexkin.cosserat",
             "flexkin.plot", "matplotlib", "bokeh", "dask")


def modules_after(args: list[str], tmp_path: Path) -> set[str]:
    out = tmp_path / "modules.json"
    env = dict(os.environ)
    src = str(ROOT / "src")
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    for _ in range(2):  # the first run may fill the caches
        subprocess.run([sys.executable, "-c", CHILD, str(out), *args], check=True, env=env, cwd=ROOT,
                       stdout=subprocess.DEVNULL, timeout=1800)
    got = json.loads(out.read_text())
    assert got["rc"] == 0
    return set(got["modules"])


def _loaded(mods: set[str], name: str) -> bool:
    return name in mods or any(m.startswith(name + ".") for m in mods)


@pytest.mark.parametrize("args", [
    ["ik", PROTO, "--pose", "0", "0", "90", "--json"],
    ["ik", PROTO, "--pose", "0", "0", "90"],
    ["fk", PROTO, "--inputs", "0.025", "0.025", "0.025", "--json"],
], ids=["ik-json", "ik-table", "fk-json"])
def test_ik_and_fk_import_nothing_heavy(args, tmp_path):
    mods = modules_after(args, tmp_path)
    assert f"flexkin.solve.{args[0]}" in mods and "numba" in mods  # the command did run its solver
    loaded = [name for name in FORBIDDEN if _loaded(mods, name)]
    assert not loaded, f"flexkin {args[0]} imported {loaded}"


def test_refine_does_import_its_integrator(tmp_path):
    """The check above can fail: the Cosserat refinement loads flexkin.cosserat."""
    mods = modules_after(["refine", PROTO, "--pose", "0", "0", "90", "--json", "--stable-only"], tmp_path)
    assert _loaded(mods, "flexkin.cosserat")


def test_console_script_flushes_and_keeps_the_exit_status(tmp_path):
    """The installed command (flexkin.cli:console) ends one-shot commands with os._exit: all of
    the output still arrives, and the exit status is main's."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT / "src") + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    cmd = [sys.executable, "-c", "from flexkin.cli import console; console()"]
    ok = subprocess.run(cmd + ["ik", PROTO, "--pose", "0", "0", "90", "--json"], env=env, cwd=ROOT,
                        capture_output=True, text=True, timeout=1800)
    assert ok.returncode == 0, ok.stderr
    d = json.loads(ok.stdout)       # the whole JSON object (tens of kB through a pipe)
    assert d["problem"] == "ik" and len(d["solutions"]) > 10
    bad = subprocess.run(cmd + ["ik", str(tmp_path / "missing.toml"), "--pose", "0", "0", "0"], env=env, cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and bad.stderr.strip() and len(bad.stderr.strip().splitlines()) == 1
