"""jgrounding: whole-body semantic-to-actuation grounding for a tendon-driven soft elephant trunk.

Pipeline (SPEC §1): response text -> (intent, intensity) -> rectified flow over Catmull-Rom
controls -> 150 x 4 tendon actuation in [0, 1] -> MuJoCo/MJX trunk motion.

Heavy parts (text encoder, generators, physics) are imported on first use, so
``import jgrounding`` stays fast.
"""

from __future__ import annotations

import importlib
import os

# MuJoCo picks its OpenGL backend when it is imported (MuJoCo 4 imports its renderer with `import mujoco`). With no
# display, software OSMesa is the one that renders on a CPU-only machine (EGL needs a GPU driver), so it is chosen
# where its library is installed (scripts/install_system.sh); without it, importing MuJoCo would fail, so nothing is
# chosen and rendering falls back to matplotlib. A user's own MUJOCO_GL wins.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    import ctypes.util

    if ctypes.util.find_library("OSMesa"):
        os.environ["MUJOCO_GL"] = "osmesa"

from jgrounding import safety
from jgrounding.actuation import splines
from jgrounding.vocabulary import INTENSITIES, INTENTS, describe, intensity_index, intent_index

__version__ = "0.1.0"

# Public name -> (module, attribute), resolved lazily.
_LAZY = {
    "ground": ("jgrounding.semantics", "ground"),
    "ground_many": ("jgrounding.semantics", "ground_many"),
    "sample": ("jgrounding.policy.sampling", "sample"),
    "SampleConfig": ("jgrounding.config", "SampleConfig"),  # jg.sample(..., config=jg.SampleConfig(steps=8))
    "load_library": ("jgrounding.library", "load_library"),
    "sim": ("jgrounding.sim", None),  # the trunk simulation, named like its package (jgrounding.sim)
    "trunk": ("jgrounding.sim", None),  # an older alias of jg.sim, kept so existing code keeps working
}

__all__ = ["INTENTS", "INTENSITIES", "describe", "intent_index", "intensity_index", "splines", "safety", *_LAZY]


def __getattr__(name):
    if name in _LAZY:
        module, attr = _LAZY[name]
        mod = importlib.import_module(module)
        value = mod if attr is None else getattr(mod, attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'jgrounding' has no attribute {name!r}")
