"""Pictures of the trunk's motion: MuJoCo's own renderer headless (OSMesa/EGL), matplotlib fallback.

- :func:`render_posture` writes a PNG of the posture at one control step (default: the last).
- :func:`render_motion` writes an animated GIF of the whole motion (every ``stride``-th control step).
- :func:`plot_backbone` draws backbones ``(n_seg + 1, 3)`` on a matplotlib 3-D axis.

If MuJoCo's renderer cannot start (no GL library), both fall back to matplotlib backbone plots, so a
picture is always produced; ``backend`` in the return value says which one made it.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import mujoco
import numpy as np

from jgrounding import trunk
from jgrounding import trunk_model as tm

log = logging.getLogger(__name__)
WIDTH, HEIGHT = 480, 360


def _camera() -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.lookat[:] = (0.2, 0.0, 0.8)
    cam.distance = 1.9
    cam.azimuth = 90.0  # side view: the user stands to the right of the trunk
    cam.elevation = -12.0
    return cam


def _frames_mujoco(u: np.ndarray, steps: list[int]) -> list[np.ndarray]:
    model = trunk.load_model()
    data = mujoco.MjData(model)
    renderer = mujoco.Renderer(model, HEIGHT, WIDTH)
    cam, frames, want = _camera(), [], set(steps)
    try:
        for t in range(u.shape[0]):
            data.ctrl[:] = u[t]
            mujoco.mj_step(model, data, nstep=trunk.SUBSTEPS)
            if t in want:
                renderer.update_scene(data, cam)
                frames.append(renderer.render().copy())
    finally:
        renderer.close()
    return frames


def plot_backbone(ax, backbone, *, color="tab:gray", alpha: float = 1.0, user: bool = True, lw: float = 4.0):
    """Draw one backbone ``(n_seg + 1, 3)`` (and the user capsule) on a 3-D axis."""
    b = np.asarray(backbone)
    ax.plot(b[:, 0], b[:, 1], b[:, 2], color=color, alpha=alpha, lw=lw, solid_capstyle="round")
    ax.scatter(*b[-1], color=color, alpha=alpha, s=12)
    if user:
        z = np.linspace(*tm.USER_TORSO_Z, 12)
        th = np.linspace(0, 2 * np.pi, 24)
        zz, tt = np.meshgrid(z, th)
        ax.plot_surface(tm.USER_TORSO_X + tm.USER_TORSO_RADIUS * np.cos(tt), tm.USER_TORSO_RADIUS * np.sin(tt), zz,
                        color="peachpuff", alpha=0.25, linewidth=0)
    ax.set_xlim(-0.45, 0.6)
    ax.set_ylim(-0.5, 0.5)
    ax.set_zlim(0.25, 1.3)
    ax.set_xlabel("x (toward user) [m]")
    ax.set_ylabel("y (left) [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=12, azim=-60)
    return ax


def _frames_matplotlib(u: np.ndarray, steps: list[int]) -> list[np.ndarray]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    backbone = trunk.rollout(u).backbone[0]
    frames = []
    for t in steps:
        fig = plt.figure(figsize=(WIDTH / 100, HEIGHT / 100), dpi=100)
        ax = fig.add_subplot(projection="3d")
        plot_backbone(ax, backbone[t])
        ax.set_title(f"t = {t * trunk.CONTROL_DT:.2f} s", fontsize=8)
        fig.canvas.draw()
        frames.append(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
        plt.close(fig)
    return frames


def frames(u, steps: list[int]) -> tuple[list[np.ndarray], str]:
    """RGB frames of the simulated motion at the given control steps, and the backend that drew them."""
    u = trunk.validate_actuation(u)[0]
    try:
        return _frames_mujoco(u, steps), "mujoco"
    except Exception as e:  # no GL context on this machine: fall back
        log.info("MuJoCo renderer unavailable (%s); using matplotlib", e)
        return _frames_matplotlib(u, steps), "matplotlib"


def _png(frame: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(frame).save(buf, format="PNG")
    return buf.getvalue()


def render_posture(u, path, step: int = -1) -> Path:
    """PNG of the posture at control ``step`` of actuation ``(150, 4)``."""
    from jgrounding.export import write_atomic

    n = np.asarray(u).shape[-2]
    (img,), _ = frames(u, [step % n])
    return write_atomic(path, _png(img))


def render_motion(u, path, stride: int = 3, fps: int = 10) -> Path:
    """Animated GIF of actuation ``(150, 4)``, one frame every ``stride`` control steps."""
    from PIL import Image

    from jgrounding.export import write_atomic

    n = np.asarray(u).shape[-2]
    imgs, _ = frames(u, list(range(0, n, stride)) + [n - 1])
    pil = [Image.fromarray(f) for f in imgs]
    buf = io.BytesIO()
    pil[0].save(buf, format="GIF", save_all=True, append_images=pil[1:], duration=int(1000 / fps), loop=0)
    return write_atomic(path, buf.getvalue())
