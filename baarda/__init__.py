"""baarda: quality-controlled aerial triangulation.

    block = baarda.read_project("examples/demo")
    result = baarda.adjust(block)            # bundle block adjustment
    qc = baarda.assess(result)               # w-tests, redundancy numbers, MDB, ...
    qc = baarda.snoop(block)                 # iterative data snooping
    print(qc.summary())
"""

from baarda.block.photo_block import Block
from baarda.bundle.bundle_quality import BundleQuality
from baarda.bundle.bundle_result import BundleResult
from baarda.errors import GeometryError, ProjectError
from baarda.io.project import read_project
from baarda.output.project_files import write_project
from baarda.pipeline import adjust, assess, prepare, read, screen, snoop
from baarda.simulate.aerial import FlightPlan, simulate_block

__all__ = ["Block", "BundleQuality", "BundleResult", "FlightPlan", "GeometryError",
           "ProjectError", "adjust", "assess", "prepare", "read", "read_project", "screen",
           "simulate_block", "snoop", "write_project"]
__version__ = "0.1.0"
