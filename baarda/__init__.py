"""baarda: quality-controlled aerial triangulation.

    block = baarda.read_project("examples/demo")
    result = baarda.adjust(block)            # bundle block adjustment
    qc = baarda.assess(result)               # w-tests, redundancy numbers, MDB, ...
    qc = baarda.snoop(block)                 # iterative data snooping
    print(qc.summary())
"""

from baarda.block.model import Block
from baarda.bundle.adjust import adjust
from baarda.bundle.quality import BundleQuality, assess, snoop
from baarda.bundle.result import BundleResult
from baarda.io.errors import GeometryError, ProjectError
from baarda.io.project import read_project, write_project
from baarda.simulate.aerial import FlightPlan, simulate_block

__all__ = ["Block", "BundleQuality", "BundleResult", "FlightPlan", "GeometryError",
           "ProjectError", "adjust", "assess", "read_project", "simulate_block", "snoop",
           "write_project"]
__version__ = "0.1.0"
