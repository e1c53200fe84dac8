"""Pictures of the trunk's motion: MuJoCo's own renderer headless (OSMesa/EGL), matplotlib fallback.

- :func:`frames` renders RGB frames at chosen control steps from one or several camera azimuths.
- :func:`render_posture` writes a PNG of the posture at one control step (default: the last).
- :func:`render_motion` writes an animated GIF of the whole motion (t = 0, then every ``stride``-th control step),
  each frame under a title (the text and its tuple, say) and its time stamp.
- :func:`render_keyframes` writes one PNG of the postures at a few moments from t = 0 (columns) from both views
  (rows), under a title.
- :func:`plot_backbone` draws backbones ``(n_seg + 1, 3)`` on a matplotlib 3-D axis.

Two views show every bending direction (the defaults of the posture and the GIF show both, side by
side): :data:`SIDE_VIEW` looks from the robot's right, so the user stands on the right of the picture
and bends toward / away from the user (tendons 0 / 2) go right / left; :data:`REAR_VIEW` looks from
behind the robot toward the user (drawn faint, behind the trunk), so bends to the robot's left / right
(tendons 1 / 3) go left / right in the picture. If MuJoCo's renderer cannot start (no GL library),
everything falls back to matplotlib backbone plots, so a picture is always produced; the returned backend
says which.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import mujoco
import numpy as np

from jgrounding import sim
from jgrounding.sim import mjcf as tm

log = logging.getLogger(__name__)
WIDTH, HEIGHT = 480, 360


# Camera azimuths (deg, MuJoCo's convention: the camera looks along (cos a, sin a) in the xy-plane).
SIDE_VIEW = 90.0  # from the robot's right (-y): the user (+x) is on the right of the picture
REAR_VIEW = 0.0  # from behind the robot toward the user: robot's left (+y) is on the left of the picture
BOTH_VIEWS = (SIDE_VIEW, REAR_VIEW)
VIEW_NAMES = {SIDE_VIEW: "side view (user on the right)", REAR_VIEW: "rear view (robot's left on the left)"}
ELEVATION = -12.0  # deg, looking slightly down
LOOKAT = (0.12, 0.0, 0.82)  # m: between the trunk and the user
DISTANCE = 1.4  # m: the trunk's whole workspace and the user in the picture
USER_ALPHA = 0.3  # the user is drawn faint: in the rear view it stands behind the trunk
GHOST_RGBA = (0.3, 0.75, 1.0, 0.9)  # ghost=True: the rest posture as a thin blue rod
GHOST_RADIUS = 0.009  # m: thinner than the trunk, so it is hidden wherever the trunk covers it


def _camera(azimuth: float = SIDE_VIEW) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.lookat[:] = LOOKAT
    cam.distance = DISTANCE
    cam.azimuth = azimuth
    cam.elevation = ELEVATION
    return cam


def _as_views(azimuth) -> tuple[float, ...]:
    views = tuple(float(a) for a in np.atleast_1d(azimuth))
    if not views or not all(np.isfinite(views)):
        raise ValueError(f"azimuth must be a finite angle in degrees or a sequence of them, got {azimuth!r}")
    return views


def _label(frame: np.ndarray, text: str, size: int = 16) -> np.ndarray:
    """Write ``text`` in the top-left corner of a frame (white with a dark outline: readable on any background)."""
    from PIL import Image, ImageDraw, ImageFont

    img = Image.fromarray(frame)
    ImageDraw.Draw(img).multiline_text(
        (8, 6),
        text,
        fill=(245, 245, 245),
        font=ImageFont.load_default(size=size),
        stroke_width=1,
        stroke_fill=(20, 20, 20),
    )
    return np.asarray(img)


def _add_ghost(model, rest, renderer) -> None:
    """Append the trunk at rest (all tendons slack) to the renderer's scene as a thin blue rod."""
    opt = mujoco.MjvOption()
    opt.sitegroup[:] = 0  # geoms only
    first = renderer.scene.ngeom
    mujoco.mjv_addGeoms(model, rest, opt, mujoco.MjvPerturb(), mujoco.mjtCatBit.mjCAT_DYNAMIC, renderer.scene)
    for i in range(first, renderer.scene.ngeom):
        renderer.scene.geoms[i].rgba[:] = GHOST_RGBA
        renderer.scene.geoms[i].size[:2] = GHOST_RADIUS  # a capsule's two radii; size[2] is its half-length


def _fade_user(model, renderer) -> None:
    user = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("user_torso", "user_head")}
    for i in range(renderer.scene.ngeom):
        g = renderer.scene.geoms[i]
        if g.objtype == mujoco.mjtObj.mjOBJ_GEOM and g.objid in user:
            g.rgba[3] = USER_ALPHA


def _frames_mujoco(
    u: np.ndarray, steps: list[int], views: tuple[float, ...], ghost: bool, trunk: str | None = None
) -> list[list[np.ndarray]]:
    model = sim.load_model(trunk)
    data, rest = mujoco.MjData(model), mujoco.MjData(model)
    mujoco.mj_forward(model, rest)
    renderer = mujoco.Renderer(model, HEIGHT, WIDTH)
    cams, frames, want = [_camera(a) for a in views], {}, set(steps)
    try:
        for t in range(max(want) + 1):
            data.ctrl[:] = u[t]
            mujoco.mj_step(model, data, nstep=sim.SUBSTEPS)
            if t in want:
                tiles = []
                for cam in cams:
                    renderer.update_scene(data, cam)
                    _fade_user(model, renderer)
                    if ghost:
                        _add_ghost(model, rest, renderer)
                    tiles.append(renderer.render().copy())
                frames[t] = tiles
    finally:
        renderer.close()
    return [frames[t] for t in steps]


def plot_backbone(ax, backbone, *, color="tab:gray", alpha: float = 1.0, user: bool = True, lw: float = 4.0):
    """Draw one backbone ``(n_seg + 1, 3)`` (and the user capsule) on a 3-D axis."""
    b = np.asarray(backbone)
    ax.plot(b[:, 0], b[:, 1], b[:, 2], color=color, alpha=alpha, lw=lw, solid_capstyle="round")
    ax.scatter(*b[-1], color=color, alpha=alpha, s=12)
    if user:
        z = np.linspace(*tm.USER_TORSO_Z, 12)
        th = np.linspace(0, 2 * np.pi, 24)
        zz, tt = np.meshgrid(z, th)
        ax.plot_surface(
            tm.USER_TORSO_X + tm.USER_TORSO_RADIUS * np.cos(tt),
            tm.USER_TORSO_RADIUS * np.sin(tt),
            zz,
            color="peachpuff",
            alpha=0.25,
            linewidth=0,
        )
    ax.set_xlim(-0.45, 0.6)
    ax.set_ylim(-0.5, 0.5)
    ax.set_zlim(0.25, 1.3)
    ax.set_xlabel("x (toward user) [m]")
    ax.set_ylabel("y (left) [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=12, azim=-60)
    return ax


def _frames_matplotlib(
    u: np.ndarray, steps: list[int], views: tuple[float, ...], ghost: bool, trunk: str | None = None
) -> list[list[np.ndarray]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    backbone = sim.rollout(u, trunk=trunk).backbone[0]
    rest = sim.rollout(np.zeros((1, sim.NUM_CHANNELS)), trunk=trunk).backbone[0, 0]
    frames = []
    for t in steps:
        tiles = []
        for azimuth in views:
            fig = plt.figure(figsize=(WIDTH / 100, HEIGHT / 100), dpi=100)
            ax = fig.add_subplot(projection="3d")
            if ghost:
                plot_backbone(ax, rest, color=GHOST_RGBA[:3], alpha=GHOST_RGBA[3], user=False, lw=1.5)
            plot_backbone(ax, backbone[t])
            # matplotlib's azim places the camera, MuJoCo's points it: they differ by 180 degrees.
            ax.view_init(elev=-ELEVATION, azim=azimuth - 180.0)
            ax.set_title(f"t = {t * sim.CONTROL_DT:.2f} s", fontsize=8)
            fig.canvas.draw()
            tiles.append(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
            plt.close(fig)
        frames.append(tiles)
    return frames


def frames(
    u,
    steps: list[int],
    azimuth=SIDE_VIEW,
    backend: str = "auto",
    *,
    labels: bool = False,
    ghost: bool = False,
    trunk: str | None = None,
) -> tuple[list[np.ndarray], str]:
    """RGB frames of the motion of actuation ``(T, 4)`` at the given control steps, and the backend used.

    ``azimuth``: one camera azimuth in degrees (:data:`SIDE_VIEW`, :data:`REAR_VIEW`, any angle) ->
    frames ``(HEIGHT, WIDTH, 3)``; or a sequence of them -> the views side by side,
    ``(HEIGHT, n_views * WIDTH, 3)``. ``labels`` writes each view's name in its corner; ``ghost`` draws
    the rest posture (all tendons slack) as a thin blue rod, for comparison.
    ``backend``: "auto" (MuJoCo's renderer, matplotlib if GL cannot start), "mujoco" or "matplotlib".
    ``trunk``: the MJCF shown (a fitted trunk; None: the shipped one).
    """
    if backend not in ("auto", "mujoco", "matplotlib"):
        raise ValueError(f"unknown backend {backend!r}; valid: auto, mujoco, matplotlib")
    views = _as_views(azimuth)
    u = sim.validate_actuation(u)[0]
    steps = [int(t) for t in steps]
    if not steps or min(steps) < 0 or max(steps) >= u.shape[0]:
        raise ValueError(f"steps must be control steps in 0..{u.shape[0] - 1}, got {steps}")
    tiles, used = None, "matplotlib"
    if backend != "matplotlib":
        try:
            tiles, used = _frames_mujoco(u, steps, views, ghost, trunk), "mujoco"
        except Exception as e:  # no GL context on this machine: fall back
            if backend == "mujoco":
                raise
            log.info("MuJoCo renderer unavailable (%s); using matplotlib", e)
    if tiles is None:
        tiles = _frames_matplotlib(u, steps, views, ghost, trunk)
    if labels:
        tiles = [[_label(f, VIEW_NAMES.get(a, f"azimuth {a:g} deg")) for f, a in zip(ts, views)] for ts in tiles]
    return [np.concatenate(ts, axis=1) for ts in tiles], used


def _png(frame: np.ndarray, colors: int | None = None) -> bytes:
    from PIL import Image

    img = Image.fromarray(frame)
    if colors is not None:  # a palette keeps multi-panel pictures small
        img = img.quantize(colors, dither=Image.Dither.NONE)
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=colors is not None)
    return buf.getvalue()


def _titled(frame: np.ndarray, text: str, size: int = 15) -> np.ndarray:
    """``frame`` under a white strip that carries ``text`` (dark, one or more lines): a picture's title."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default(size=size)
    lines = text.count("\n") + 1
    strip = Image.new("RGB", (frame.shape[1], lines * (size + 4) + 10), (255, 255, 255))
    ImageDraw.Draw(strip).multiline_text((8, 5), text, fill=(20, 20, 20), font=font, spacing=4)
    return np.concatenate([np.asarray(strip), frame], axis=0)


def _stamp(t: int) -> str:
    """The time stamp of control step ``t``."""
    return f"t = {t * sim.CONTROL_DT:.2f} s"


def render_posture(u, path, step: int = -1, azimuth=BOTH_VIEWS, title: str = "", trunk: str | None = None) -> Path:
    """PNG of the posture at control ``step`` of actuation ``(150, 4)`` (default: both views, labelled),
    under ``title`` and the step's time stamp."""
    from jgrounding.io import write_atomic

    n = np.asarray(u).shape[-2]
    step = step % n
    (img,), _ = frames(u, [step], azimuth, labels=True, trunk=trunk)
    return write_atomic(path, _png(_titled(img, f"{title}   {_stamp(step)}" if title else _stamp(step))))


def motion_steps(n: int, stride: int = 5) -> list[int]:
    """The control steps a GIF of ``n`` steps shows: t = 0, every ``stride``-th step, and the last."""
    if n < 1 or stride < 1:
        raise ValueError(f"need at least one control step and a stride >= 1, got n={n}, stride={stride}")
    return sorted(set(range(0, n, stride)) | {n - 1})


def motion_frames(
    u, stride: int = 5, azimuth=BOTH_VIEWS, title: str = "", trunk: str | None = None
) -> tuple[list[int], list[np.ndarray]]:
    """The frames of :func:`render_motion`: the control steps shown (from t = 0) and one RGB picture per step,
    each under ``title`` and its time stamp."""
    steps = motion_steps(np.asarray(u).shape[-2], stride)
    imgs, _ = frames(u, steps, azimuth, labels=True, trunk=trunk)
    return steps, [_titled(f, f"{title}   {_stamp(t)}" if title else _stamp(t)) for f, t in zip(imgs, steps)]


def render_motion(
    u, path, stride: int = 5, fps: float = 6.0, azimuth=BOTH_VIEWS, title: str = "", trunk: str | None = None
) -> Path:
    """Animated GIF of actuation ``(150, 4)``, one frame every ``stride`` control steps from t = 0 to the last
    step (default: both views), each frame under ``title`` (e.g. the text and its tuple) and its time stamp.

    The defaults play in real time (5 control steps of 1/30 s per frame at 6 frames per second).
    """
    from PIL import Image

    from jgrounding.io import write_atomic

    _, imgs = motion_frames(u, stride, azimuth, title, trunk)
    pil = [Image.fromarray(f) for f in imgs]
    buf = io.BytesIO()
    pil[0].save(buf, format="GIF", save_all=True, append_images=pil[1:], duration=int(1000 / fps), loop=0)
    return write_atomic(path, buf.getvalue())


KEYFRAME_STEPS = (0, 30, 60, 90, 120, 149)  # t = 0, 1, 2, 3, 4, 5 s


def keyframes(
    u, steps=None, azimuth=BOTH_VIEWS, scale: float = 0.6, title: str = "", trunk: str | None = None
) -> np.ndarray:
    """One RGB picture of the postures of actuation ``(T, 4)`` at ``steps`` (columns) from each view (rows),
    each tile ``scale`` times the frame size and labelled with its time (the first column with its view),
    under ``title`` when one is given (e.g. the text and its tuple).
    ``steps`` defaults to :data:`KEYFRAME_STEPS` (six moments, 1 s apart from t = 0, for T = 150)."""
    from PIL import Image

    views = _as_views(azimuth)
    if steps is None:
        n = np.asarray(u).shape[-2]
        steps = KEYFRAME_STEPS if n == sim.NUM_STEPS else tuple(np.linspace(0, n - 1, 6).astype(int))
    imgs, _ = frames(u, list(steps), views, trunk=trunk)
    w, h = int(WIDTH * scale), int(HEIGHT * scale)
    rows = []
    for v, a in enumerate(views):
        tiles = []
        for c, (img, t) in enumerate(zip(imgs, steps)):
            tile = np.asarray(Image.fromarray(img[:, v * WIDTH : (v + 1) * WIDTH]).resize((w, h), Image.LANCZOS))
            text = _stamp(t) + (f"\n{VIEW_NAMES.get(a, f'azimuth {a:g}')}" if c == 0 else "")
            tiles.append(np.pad(_label(tile, text, size=13), ((0, 2), (0, 2), (0, 0)), constant_values=255))
        rows.append(np.concatenate(tiles, axis=1))
    picture = np.concatenate(rows, axis=0)[:-2, :-2]
    return _titled(picture, title) if title else picture


def render_keyframes(u, path, steps=None, azimuth=BOTH_VIEWS, title: str = "", trunk: str | None = None) -> Path:
    """PNG of :func:`keyframes`: the motion of actuation ``(150, 4)`` at a glance, under ``title``."""
    from jgrounding.io import write_atomic

    return write_atomic(path, _png(keyframes(u, steps, azimuth, title=title, trunk=trunk), colors=256))
