"""The live renderer: a scene in, an image out, rerunning only the stages an edit touched.

render_engine.py holds the stages and their caches; async_render.py the worker thread; the other
modules keep an edit's work small (cropped_encoder, paint_replay, light_merge, receptive) and fast
(onednn).
"""

import os
import sys
import warnings

# OpenMP reads this when torch loads it: passive waiting keeps idle worker threads from spinning,
# which made 2-thread rendering 10x slower when other processes shared the cores (measured here).
if "torch" in sys.modules and "OMP_WAIT_POLICY" not in os.environ:
    warnings.warn("models.engine was imported after torch, so OMP_WAIT_POLICY=PASSIVE is not in effect and "
                  "rendering may be 10x slower on a shared CPU: import models.engine first, or set the variable",
                  stacklevel=2)
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from models.engine.async_render import AsyncRenderer  # noqa: E402
from models.engine.render_engine import RenderEngine, RenderReport, resolve_device, resolve_precision  # noqa: E402

__all__ = ["AsyncRenderer", "RenderEngine", "RenderReport", "resolve_device", "resolve_precision"]
