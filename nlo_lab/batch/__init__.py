"""A whole corpus to robot motion on dask.distributed (``nlo-lab batch``).

:func:`retarget_many` reads every input (files, folders, manifests: :func:`find_inputs`),
retargets each on a worker of a dask.distributed cluster (a ``LocalCluster`` by default) and
writes one output folder per input, as ``nlo-lab retarget --out`` does, plus ``summary.json``
and a results table ``results.csv`` (:data:`COLUMNS`). A run resumes where an earlier one
stopped (:mod:`nlo_lab.batch.plan`). dask is imported only when something has to run: the
``batch`` extra (``pip install "nlo_lab[batch]"``).
"""

from nlo_lab.batch.engine import CONNECT_TIMEOUT, SchedulerError, available_cores, retarget_many, to_frame
from nlo_lab.batch.inputs import MANIFEST_SUFFIX, RESULTS_FILE, SUFFIXES, BatchInput, InputError, file_sha256, find_inputs
from nlo_lab.batch.output_folder import OUTPUT_FILES, SUMMARY_FILE, finite_or_null, read_summary, write_output_folder
from nlo_lab.batch.settings import BatchSettings, robot_files
from nlo_lab.batch.table import COLUMNS, QUALITY, STATUSES

__all__ = [
    "retarget_many", "to_frame", "available_cores", "CONNECT_TIMEOUT", "SchedulerError",
    "find_inputs", "file_sha256", "BatchInput", "InputError", "SUFFIXES", "MANIFEST_SUFFIX", "RESULTS_FILE",
    "BatchSettings", "robot_files",
    "COLUMNS", "QUALITY", "STATUSES",
    "OUTPUT_FILES", "SUMMARY_FILE", "write_output_folder", "read_summary", "finite_or_null",
]
