"""The co-simulation master on FMPy: generic, knows nothing about robots.

Its folders are its concepts, from the bottom up (each imports only those below it):

* ``messages``: errors, counts in words, suggestions; the lazy faces (each folder's exports listed once);
* ``model``: what an FMU is before it runs (model description, binary, archive, units, file kinds);
* ``instances``: the instance contract and its implementations (in process, Model Exchange, isolated);
* ``stepping``: the algorithm contract, the table of algorithms and the algorithms;
* ``requirements``: requirements in signal temporal logic, their check and their online monitor;
* ``scenario``: scenario documents (TOML, conditions, input tables);
* ``plan``: a scenario resolved against its FMUs (records, coupling structure, wiring, SSP);
* ``results``: the recording and the results folder;
* ``runtime``: the execution, its observers and manipulators, start-up, pacing, protocols;
* ``linearisation``: linear models of FMUs and of the system around a point of a run, loops and margins.

This face exports what the application and users' scripts use; each folder's face exports its own.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .instances import SOLVERS, SolverSpec
    from .linearisation import LinearModel, Linearisation, Linearizer, LoopAnalysis, Request
    from .messages import (CosimError, FmuLoadError, MissingVariableError, OtherFileError, OutputError, RunError,
                           ScenarioError, close_names, count, did_you_mean, unknown_key)
    from .model import (CO_SIMULATION, DEFAULT_LIMITS, MODEL_EXCHANGE, ArchiveLimits, FileKind, FmuModel,
                        LimitOverrides, Variable, check_archive, file_kind, fmi_version, limit_overrides,
                        load_model, named_kind)
    from .requirements import FormulaError, Outcome, formula_fold
    from .plan import (PARAMETERS, Plan, describe_coupling, export_fmu, export_remarks, export_ssp, is_ssp, load_ssp,
                       resolve, variable)
    from .results import (RECORDING, RESULT_FORMATS, MatLayout, OutputLock, ResultFormat, ResultsError, RunResult,
                          RunStatus, format_flags, format_help, layout, make_folder, read_json, read_signals,
                          write_json, write_mat)
    from .runtime import (Execution, Manipulator, Observer, Protocol, check_protocol, plan_runs, read_protocol, run,
                          run_protocol)
    from .scenario import (SET_TABLES, Scenario, apply_overrides, base_path, is_path, load, parse, parse_set,
                           parse_value, read_document, read_toml, settable_table)
    from .stepping import (Adaptive, AdaptiveSpec, Algorithm, GaussSeidel, Iterated, IterationSpec, Jacobi,
                           MultiRate, ParallelJacobi, describe_settings)

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
