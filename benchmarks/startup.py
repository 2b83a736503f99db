"""Where the start-up of ``flexkin ik examples/prototype_3pfr.toml --pose 0 0 90 --json`` goes.

Run::

    python benchmarks/startup.py [--repeat N] [--json PATH] [-- CLI ARGUMENTS ...]

Each run starts a fresh interpreter that runs the command as the console script does
(``flexkin.cli.main``, ended like ``flexkin.cli.console``; output to ``/dev/null``), instrumented:

* **imports**: the execution of modules outside the kernels' first calls (all of them: at
  start-up and the lazy ones inside the command), by top-level package (self time: a module's
  own execution, without the modules it imports);
* **numba initialisation**: numba's one-off set-up at the first compiled call (its typing and
  target registries, and the ``scipy.linalg`` that numba itself imports to find BLAS), measured
  apart by forcing it first;
* **kernel loading**: the first call of each compiled kernel, which loads its machine code from
  the on-disk cache (listed per kernel with ``--kernels``);
* **solve**: the IK call minus the two items above;
* **to_dict**, **JSON + print**: the SPEC §4 object and its text;
* **interpreter start and exit**: the whole process (timed from outside) minus the rest.

Times are process CPU seconds (steadier than wall-clock time on a shared machine); the whole
process is given in wall-clock and CPU time (user + system of the child).  Medians of ``N``
runs after one warm-up run (which also fills the kernel cache if it is empty).  The header
gives the load average: compare runs only on an otherwise idle machine.

``--pycache DIR`` lets the children keep Python's compiled bytecode in ``DIR`` (it unsets
``PYTHONDONTWRITEBYTECODE`` and sets ``PYTHONPYCACHEPREFIX``), as an installed package has it;
without it they run in the caller's environment, where ``PYTHONDONTWRITEBYTECODE=1`` makes
every process compile flexkin's modules from source again.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_ARGS = ["ik", str(ROOT / "examples" / "prototype_3pfr.toml"), "--pose", "0", "0", "90", "--json"]

#: the instrumented child: prints one JSON line on stderr
CHILD = r"""
import json, os, sys, time, threading
T = time.process_time
t_start = T()
state = {"imports": {}, "kernels": [], "phase": {}, "stack": [], "in_kernel": 0, "modules": {}}
_tls = threading.local()


class _Proxy:
    # a module loader whose create/exec steps are timed (self time: minus nested imports)
    def __init__(self, loader, name):
        self._loader, self._name = loader, name

    def __getattr__(self, attr):
        return getattr(self._loader, attr)

    def _timed(self, fn, *a):
        st = state["stack"]
        st.append(0.0)
        t = T()
        try:
            return fn(*a)
        finally:
            dt = T() - t
            nested = st.pop()
            if st:
                st[-1] += dt
            _charge(self._name, dt - nested)

    def create_module(self, spec):
        f = getattr(self._loader, "create_module", None)
        return None if f is None else self._timed(f, spec)

    def exec_module(self, module):
        return self._timed(self._loader.exec_module, module)


def _charge(name, dt):
    key = "kernel" if state["in_kernel"] else "import"
    pkg = name.split(".")[0]
    d = state["imports"].setdefault(key, {})
    d[pkg] = d.get(pkg, 0.0) + dt
    if key == "import":
        state["modules"][name] = state["modules"].get(name, 0.0) + dt


class _Finder:
    def find_spec(self, name, path, target=None):
        if getattr(_tls, "busy", False):
            return None
        _tls.busy = True
        t = T()
        try:
            spec = None
            for f in sys.meta_path:
                if f is self or not hasattr(f, "find_spec"):
                    continue
                spec = f.find_spec(name, path, target)
                if spec is not None:
                    break
        finally:
            _tls.busy = False
        dt = T() - t
        if state["stack"]:
            state["stack"][-1] += dt
        _charge(name, dt)
        if spec is not None and spec.loader is not None and hasattr(spec.loader, "exec_module"):
            spec.loader = _Proxy(spec.loader, name)
        return spec


sys.meta_path.insert(0, _Finder())
import numba  # noqa: E402
from numba.core import dispatcher as _nd  # noqa: E402
from numba.core.registry import cpu_target  # noqa: E402

t = T()
state["in_kernel"] += 1
cpu_target.target_context.refresh()
cpu_target.typing_context.refresh()
state["in_kernel"] -= 1
state["phase"]["numba initialisation"] = T() - t
_compile = _nd.Dispatcher._compile_for_args


def first_call(self, *a, **k):
    state["in_kernel"] += 1
    t = T()
    try:
        return _compile(self, *a, **k)
    finally:
        state["in_kernel"] -= 1
        state["kernels"].append([self.py_func.__module__ + "." + self.py_func.__qualname__, T() - t])


_nd.Dispatcher._compile_for_args = first_call
import flexkin.cli as cli  # noqa: E402
import flexkin.results as results  # noqa: E402


def _imports():
    return sum(state["imports"].get("import", {}).values())


def wrap(owner, name, phase):
    f = getattr(owner, name)

    def w(*a, **k):
        t = T()
        k0 = sum(x[1] for x in state["kernels"])
        i0 = _imports()
        try:
            return f(*a, **k)
        finally:
            dt = T() - t
            dk = sum(x[1] for x in state["kernels"]) - k0
            state["phase"][phase] = state["phase"].get(phase, 0.0) + dt - dk - (_imports() - i0)
    setattr(owner, name, w)


if ARGS[0] in ("ik", "fk"):  # the solver the command calls (imported as the command would)
    import importlib  # noqa: E402
    wrap(importlib.import_module("flexkin.solve." + ARGS[0]), ARGS[0], "solve")
wrap(results.KinematicsResult, "to_dict", "to_dict")
wrap(cli, "_dump", "JSON + print")
sys.stdout = open(os.devnull, "w")
rc = cli.main(ARGS)
sys.stdout = sys.__stdout__
state["phase"]["kernel loading"] = sum(x[1] for x in state["kernels"])
state["phase"]["imports"] = _imports()
state["phase"]["all inside the interpreter"] = T() - t_start
state["rc"] = rc
state["scipy"] = sorted(m for m in sys.modules if m.startswith("scipy.") and m.count(".") == 1)
del state["stack"]
print("@@" + json.dumps(state), file=sys.stderr)
if hasattr(cli, "console") and ARGS[0] in ("ik", "fk"):  # end as the console script ends the command
    sys.stderr.flush()
    os._exit(rc)
"""


ENV = dict(os.environ)


def _run_child(args: list[str]) -> tuple[dict, float, float]:
    code = CHILD.replace("ARGS", repr(args))
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=ENV)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    line = next((ln for ln in p.stderr.splitlines() if ln.startswith("@@")), None)
    if p.returncode or line is None:
        raise RuntimeError(f"the instrumented run failed ({p.returncode}): {p.stderr[-2000:]}")
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return json.loads(line[2:]), wall, cpu


def _plain(args: list[str]) -> tuple[float, float]:
    """Wall and CPU seconds of the command as the console script runs it (no instrumentation)."""
    code = ("import sys, flexkin.cli as c\n"
            "c.console() if hasattr(c, 'console') else sys.exit(c.main())")  # as the installed command
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code, *args], check=True, cwd=ROOT, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, env=ENV)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="runs after a warm-up (default 5)")
    ap.add_argument("--json", metavar="PATH", help="also write the medians as JSON")
    ap.add_argument("--kernels", action="store_true", help="list the load time of every kernel")
    ap.add_argument("--modules", action="store_true", help="list the 25 slowest modules to import (self time)")
    ap.add_argument("--pycache", metavar="DIR", help="keep compiled bytecode in DIR (see above)")
    ap.add_argument("cli", nargs=argparse.REMAINDER, help="the flexkin arguments (default: the IK row)")
    a = ap.parse_args(argv)
    args = [x for x in a.cli if x != "--"] or DEFAULT_ARGS
    if a.pycache:
        ENV.pop("PYTHONDONTWRITEBYTECODE", None)
        ENV["PYTHONPYCACHEPREFIX"] = str(Path(a.pycache).resolve())
    _plain(args)  # warm-up (fills the kernel cache if needed)
    plain = [_plain(args) for _ in range(a.repeat)]
    runs = [_run_child(args) for _ in range(a.repeat)]
    load = os.getloadavg()
    med = statistics.median
    whole_wall = med(p[0] for p in plain)
    whole_cpu = med(p[1] for p in plain)
    phases: dict[str, list[float]] = {}
    for st, _, cpu in runs:
        ph = dict(st["phase"])
        ph["interpreter start and exit"] = cpu - ph.pop("all inside the interpreter")
        for k, v in ph.items():
            phases.setdefault(k, []).append(v)
    order = ["interpreter start and exit", "imports", "numba initialisation", "kernel loading", "solve", "to_dict",
             "JSON + print"]
    imports: dict[str, list[float]] = {}
    in_numba: dict[str, list[float]] = {}
    modules: dict[str, list[float]] = {}
    kernels: dict[str, list[float]] = {}
    for st, _, _ in runs:
        for k, v in st["imports"].get("import", {}).items():
            imports.setdefault(k, []).append(v)
        for k, v in st["imports"].get("kernel", {}).items():
            in_numba.setdefault(k, []).append(v)
        for k, v in st["modules"].items():
            modules.setdefault(k, []).append(v)
        for k, v in st["kernels"]:
            kernels.setdefault(k, []).append(v)

    def by_package(d: dict[str, list[float]]) -> str:
        return ", ".join(f"{k} {med(v + [0.0] * (a.repeat - len(v))):.3f}"
                         for k, v in sorted(d.items(), key=lambda kv: -med(kv[1])) if med(v) >= 0.002)
    print(f"flexkin {' '.join(args)}")
    print(f"load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}, {os.cpu_count()} cores; medians of "
          f"{a.repeat} runs; " + (f"bytecode kept in {a.pycache}" if a.pycache else
                                  "PYTHONDONTWRITEBYTECODE=" + ENV.get("PYTHONDONTWRITEBYTECODE", "")))
    print(f"  whole process: {whole_wall:.3f} s wall, {whole_cpu:.3f} s CPU")
    print("  CPU seconds by phase (instrumented runs):")
    rows = {}
    for k in order:
        if k in phases:
            rows[k] = med(phases[k])
            print(f"    {k:<28} {rows[k]:7.3f}")
    print(f"  imports by package (CPU s, module execution): {by_package(imports)}")
    print(f"  imports made by numba's initialisation and the kernels' first calls: {by_package(in_numba)}")
    if a.modules:
        for k, v in sorted(modules.items(), key=lambda kv: -med(kv[1]))[:25]:
            print(f"    {1e3 * med(v):7.1f} ms  {k}")
    nk = [len(st["kernels"]) for st, _, _ in runs]
    print(f"  kernels loaded: {med(nk):.0f} first calls")
    if a.kernels:
        for k, v in sorted(kernels.items(), key=lambda kv: -med(kv[1])):
            print(f"    {1e3 * med(v):7.1f} ms  {k} (x{len(v) // a.repeat})")
    print(f"  scipy subpackages imported: {', '.join(runs[0][0]['scipy'])}")
    if a.json:
        Path(a.json).write_text(json.dumps({
            "args": args, "loadavg": list(load), "repeat": a.repeat, "pycache": a.pycache, "whole_wall_s": whole_wall,
            "whole_cpu_s": whole_cpu, "phases_cpu_s": rows,
            "imports_cpu_s": {k: med(v) for k, v in imports.items()},
            "imports_in_numba_cpu_s": {k: med(v) for k, v in in_numba.items()},
            "kernels_cpu_s": {k: med(v) for k, v in kernels.items()},
            "scipy": runs[0][0]["scipy"]}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
