"""baarda: quality-controlled aerial triangulation.

    block = baarda.read("examples/demo")     # native, COLMAP, BAL, DBAT, PhotoModeler, AICON
    result = baarda.adjust(block)            # bundle block adjustment (what `baarda adjust` does)
    qc = baarda.assess(result)               # w-tests, redundancy numbers, MDB, ...
    qc = baarda.snoop(block)                 # iterative data snooping
    print(qc.summary())
    qc.table()                               # one row per observation component (pandas)

    models = baarda.read_models("models/")   # independent models (FOTEF)
    bq = baarda.adjust_models(models)        # pre-adjustment, adjustment, snooping, tests

Every name is loaded on first use (`import baarda` stays light); the table below says where
each lives.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_WHERE = {
    # the pipeline: read any input, adjust it, assess it, snoop it, screen it
    "read": "baarda.pipeline", "prepare": "baarda.pipeline", "adjust": "baarda.pipeline",
    "assess": "baarda.pipeline", "snoop": "baarda.pipeline", "screen": "baarda.pipeline",
    "read_models": "baarda.pipeline", "adjust_models": "baarda.pipeline",
    "read_configured": "baarda.io.configuration",
    # planning, simulation, on-line relative orientation
    "plan": "baarda.planning.design_reliability",
    "ControlLayout": "baarda.planning.design",
    "modified_snoop": "baarda.planning.modified_snoop",
    "FlightPlan": "baarda.simulate.aerial", "simulate_block": "baarda.simulate.aerial",
    "ModelPlan": "baarda.simulate.model_blocks", "simulate_models": "baarda.simulate.model_blocks",
    "OnlineSession": "baarda.relative.session", "OnlineBundle": "baarda.online.bundle",
    "ScreeningOptions": "baarda.screening.chain",
    # data, results, options, errors
    "Block": "baarda.block.photo_block", "ModelBlock": "baarda.block.model_block",
    "BundleResult": "baarda.bundle.bundle_result", "Assessment": "baarda.quality.assessment",
    "BlockQuality": "baarda.independent.workflow",
    "TestOptions": "baarda.options", "SolveOptions": "baarda.options",
    "Requested": "baarda.options", "Config": "baarda.options",
    "GeometryError": "baarda.errors", "ProjectError": "baarda.errors",
    # project files
    "read_project": "baarda.io.project", "write_project": "baarda.output.project_files",
    "write_results": "baarda.output.bundle_results",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'baarda' has no attribute '{name}'")
    value = getattr(importlib.import_module(where), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
