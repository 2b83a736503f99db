"""Design studies: sweeps over mechanism parameters, computed on Dask.

>>> from flexkin.study import run_study                                   # doctest: +SKIP
>>> res = run_study("examples/study_3rfr.toml", "study_out", workers=2)     # doctest: +SKIP
>>> res.parquet, res.n_computed, res.rows[0]["workspace_area"]            # doctest: +SKIP

The study file format is described in ``docs/study.md``; :mod:`.grid` defines the design
parameters (dotted keys), :mod:`.evaluate` the per-(design, orientation) computation and its
metrics, :mod:`.run` the execution on Dask, :mod:`.table` the files written.  Dask and
matplotlib are imported only when a study runs.
"""

from __future__ import annotations

from typing import Any

__all__ = ["run_study", "StudyResult", "StudySpec", "StudyError", "StudyAborted", "StudyInterrupted", "load_study",
           "study_from_dict", "read_table", "evaluate_design", "DesignTask", "METRICS", "SYNCHRONOUS"]

#: public name -> submodule, resolved on first use (PEP 562): ``flexkin``'s command line imports
#: :mod:`.cli` for its parser without loading the study machinery
_LAZY = {"run_study": "run", "StudyResult": "run", "SYNCHRONOUS": "run", "StudyAborted": "run",
         "StudyInterrupted": "run", "StudySpec": "spec", "StudyError": "spec", "load_study": "spec", "study_from_dict": "spec", "read_table": "table", "evaluate_design": "evaluate",
         "DesignTask": "evaluate", "METRICS": "evaluate"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
