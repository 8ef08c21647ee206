"""The live renderer: a scene in, an image out, rerunning only the stages an edit touched.

render_engine.py holds the stages and their caches; async_render.py the worker thread; the other
modules keep an edit's work small (cropped_encoder, paint_replay, light_merge, receptive) and fast
(onednn).
"""

import os
import sys
import warnings

# OpenMP reads these when torch loads it. Idle worker threads must not spin for long: spinning made
# 2-thread rendering 10x slower when other processes shared the cores. Yet a short spin (GNU OpenMP's
# GOMP_SPINCOUNT, which overrides the passive policy) bridges the microseconds between a network's
# layers: faster on an idle machine, a little slower with another job beside it (docs/results.md, "Measurements behind the code").
OPENMP_WAITING = {"OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": "3000"}
if "torch" in sys.modules and not OPENMP_WAITING.keys() & os.environ.keys():
    warnings.warn("models.engine was imported after torch, so OpenMP's waiting (OMP_WAIT_POLICY, GOMP_SPINCOUNT) "
                  "is not set and rendering may be 10x slower on a shared CPU: import models.engine first, "
                  "or set the variables", stacklevel=2)
for _name, _value in OPENMP_WAITING.items():
    os.environ.setdefault(_name, _value)

from models.engine.async_render import AsyncRenderer  # noqa: E402
from models.engine.render_engine import RenderEngine, RenderReport, resolve_device, resolve_precision  # noqa: E402

__all__ = ["AsyncRenderer", "RenderEngine", "RenderReport", "resolve_device", "resolve_precision"]
