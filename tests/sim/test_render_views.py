"""The two camera views show what the docs say they show: in the side view the user is on the right, in the
rear view the robot's left is on the left; several views tile side by side; the fallback draws them too."""

import ctypes.util

import numpy as np
import pytest

from jgrounding import sim
from jgrounding.sim import render


def held(level, steps: int = 60) -> np.ndarray:
    """Commands easing from slack to ``level`` (4 pulls) within 30 control steps, then held."""
    s = np.clip(np.arange(steps) / 30, 0.0, 1.0)
    return ((0.5 - 0.5 * np.cos(np.pi * s))[:, None] * np.asarray(level, float)[None]).astype(np.float32)


# The Makefile installs OSMesa (scripts/install_system.sh); only where that optional step could not run
# is there no library to render with, and the views are then checked through the fallback test below.
# With the library present, a renderer that fails is a failure, not a skip.
_HAS_GL = any(ctypes.util.find_library(name) for name in ("OSMesa", "EGL"))
needs_gl = pytest.mark.skipif(not _HAS_GL, reason="no OSMesa/EGL library: MuJoCo cannot render here")


def _last_frame(u, view):
    (img,), used = render.frames(u, [len(u) - 1], view, backend="mujoco")
    return img.astype(int)


def _moved_column(u, view) -> float:
    """Mean image column of the pixels that differ from the rest posture (where the trunk went)."""
    rest, img = _last_frame(held([0, 0, 0, 0]), view), _last_frame(u, view)
    changed = np.abs(img - rest).sum(-1) > 60
    assert changed.sum() > 50, "the bend did not change the picture"
    return float(np.nonzero(changed)[1].mean())


@needs_gl
def test_side_view_puts_the_user_on_the_right():
    assert sim.rollout(held([0.6, 0, 0, 0])).tip[0, -1, 0] > 0.1  # tendon 0 bends toward the user (+x)
    toward = _moved_column(held([0.6, 0, 0, 0]), render.SIDE_VIEW)
    away = _moved_column(held([0, 0, 0.6, 0]), render.SIDE_VIEW)
    assert away < toward


@needs_gl
def test_rear_view_puts_the_robots_left_on_the_left():
    left = _moved_column(held([0, 0.6, 0, 0]), render.REAR_VIEW)
    right = _moved_column(held([0, 0, 0, 0.6]), render.REAR_VIEW)
    assert left < render.WIDTH / 2 < right


def test_views_tile_and_the_matplotlib_fallback_draws_them():
    u = held([0.3, 0.3, 0, 0])
    imgs, used = render.frames(u, [10, 59], render.BOTH_VIEWS, backend="matplotlib", labels=True, ghost=True)
    assert used == "matplotlib" and len(imgs) == 2
    assert imgs[0].shape == (render.HEIGHT, 2 * render.WIDTH, 3) and imgs[0].dtype == np.uint8
    with pytest.raises(ValueError, match="backend"):
        render.frames(u, [0], backend="opengl")
    with pytest.raises(ValueError, match="steps"):
        render.frames(u, [60])


def _strip_rows(img: np.ndarray) -> int:
    """Rows of white title strip above the picture (the first rows that are mostly white)."""
    white = (img > 240).all(-1).mean(1) > 0.6
    return int(np.argmin(white)) if not white.all() else len(white)


def test_the_gif_starts_at_t0_and_every_frame_carries_the_title_and_its_time():
    assert render.motion_steps(150)[:2] == [0, 5] and render.motion_steps(150)[-1] == 149
    u = held([0.4, 0, 0, 0.2])
    steps, imgs = render.motion_frames(u, stride=20, title='"wave hello" -> (greeting, moderate)')
    assert steps == [0, 20, 40, 59]
    assert all(img.shape[0] > render.HEIGHT for img in imgs)  # a title strip above each frame
    strip = [img[: img.shape[0] - render.HEIGHT] for img in imgs]
    assert all((s < 128).any() for s in strip), "the title strip has no text"
    assert not np.array_equal(strip[0], strip[1]), "the time stamp does not change between frames"
    _, plain = render.motion_frames(u, stride=20)
    assert not np.array_equal(strip[0], plain[0][: plain[0].shape[0] - render.HEIGHT])  # the title is written
    with pytest.raises(ValueError, match="stride"):
        render.motion_steps(150, stride=0)


def test_keyframes_start_at_t0_and_carry_a_title():
    assert render.KEYFRAME_STEPS[0] == 0 and render.KEYFRAME_STEPS[-1] == sim.NUM_STEPS - 1
    u = held([0.3, 0.3, 0, 0], steps=sim.NUM_STEPS)
    plain = render.keyframes(u, azimuth=render.SIDE_VIEW)
    titled = render.keyframes(u, azimuth=render.SIDE_VIEW, title="(nodding, subtle)")
    assert plain.shape[1] == titled.shape[1] and titled.shape[0] > plain.shape[0]
    assert plain.shape[1] >= len(render.KEYFRAME_STEPS) * int(render.WIDTH * 0.6)  # one column per moment
