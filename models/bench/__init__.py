"""`nvr bench`: every renderer on the same scenes in one process, speed against error.

benchmark.py runs it; scenes.py picks the scenes, system.py describes the machine and measures
memory, plot.py draws the speed-against-error figure, report.py writes the Markdown page.
"""

import models.engine  # noqa: F401 - first, so OMP_WAIT_POLICY is set before torch loads OpenMP
from models.bench.benchmark import FULL, QUICK, run_bench, write_outputs  # noqa: E402

__all__ = ["FULL", "QUICK", "run_bench", "write_outputs"]
