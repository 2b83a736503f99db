"""Design studies: sweeps over mechanism parameters, computed on Dask.

>>> from flexkin.study import run_study                                   # doctest: +SKIP
>>> res = run_study("examples/study_3rfr.toml", "study_out", workers=2)     # doctest: +SKIP
>>> res.parquet, res.n_computed, res.rows[0]["workspace_area"]            # doctest: +SKIP

The study file format is described in ``docs/study.md``; :mod:`.grid` defines the design
parameters (dotted keys), :mod:`.evaluate` the per-(design, orientation) computation and its
metrics, :mod:`.run` the execution on Dask, :mod:`.table` the files written.  Dask and
matplotlib are imported only when a study runs.
"""

from .evaluate import METRICS, DesignTask, evaluate_design
from .run import SYNCHRONOUS, StudyAborted, StudyInterrupted, StudyResult, run_study
from .spec import StudyError, StudySpec, load_study, study_from_dict
from .table import read_table

__all__ = ["run_study", "StudyResult", "StudySpec", "StudyError", "StudyAborted", "StudyInterrupted", "load_study",
           "study_from_dict", "read_table", "evaluate_design", "DesignTask", "METRICS", "SYNCHRONOUS"]
