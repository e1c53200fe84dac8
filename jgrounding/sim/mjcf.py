"""MJCF builder for the tendon-driven soft elephant trunk; ``python -m jgrounding.sim.model`` writes it (the shipped
``jgrounding/assets/trunk.xml``, or a trunk from its TOML description).

The trunk hangs from the robot's "face" (base at z = BASE_HEIGHT) and is a tapered chain of
``NUM_SEGMENTS`` capsules. Every joint between segments has two bending hinges (about x and y) and a
short axial slide, with stiffness and damping that fall geometrically toward the tip, so a uniform
tendon pull bends the distal part more: the tip curls, as an elephant's does.

Tendons. Four *fixed* tendons at 0, 90, 180, 270 degrees around the backbone (0 faces the user at +x,
1 the robot's left +y, 2 away -x, 3 right -y). Tendon j's length is sum_i r_i * (bending of joint i
toward side j) + sum_i s_i (axial slides): the constant-curvature approximation that tendon-driven
continuum robots are commonly modelled with, with the routing radius r_i tapering like the body.
Pulling one tendon bends the trunk toward its side; pulling all four (co-contraction) cancels the
bending and compresses the axial slides, so the trunk shortens (retract); all slack lets it hang at
full length (extend). We chose fixed over spatial (site-routed) tendons: the same bend / curl /
retract behaviour for the primitives with fewer kinematic terms (no wrapping geometry per step), and
the model of the continuum-robot literature. Compile time did not decide it: SPEC §8 measured the same
16 s single-step MJX compile for the fixed- and the spatial-tendon trunk on the pinned stack.

Actuators. One ``motor`` per tendon, ``ctrlrange = [0, 1]`` (normalized pull, 0 = slack), with a
negative gear of ``MAX_TENDON_FORCE`` so that ``u = 1`` pulls with the largest safe force. A motor
(force source, no position loop) is what a tendon driven by a torque-controlled winch does, and it
keeps the map u -> shape quasi-static and smooth; the commands are already smooth (Catmull-Rom +
slew limit).

Timestep. ``implicitfast`` (MJX supports it; not ``implicit``) with dt = 1/120 s: the joint damping
is integrated implicitly, which keeps the stiff, light distal joints stable at 4 physics substeps per
control step (control at 30 Hz, 150 steps = 5 s of motion).

The user is a capsule torso and a sphere head in front of the robot at +x, so reach, proximity and
contact can be measured. Contacts are explicit ``<pair>``s of the torso with the distal segments
(``CONTACT_SEGMENTS``): the only pairs that can touch.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from pathlib import Path

from jgrounding.io import asset, read_toml

NUM_SEGMENTS = 10
TRUNK_LENGTH = 0.70  # m
BASE_HEIGHT = 1.10  # m, the trunk's root
BASE_RADIUS, TIP_RADIUS = 0.045, 0.014  # m
TIMESTEP = 1.0 / 120.0  # 1/60 s blows up (slides + light tip); 1/120 matches 1/240 within 1 mm
MAX_TENDON_FORCE = 14.0  # N at u = 1: a strong curl, not a full coil
ROOT_STIFFNESS, TIP_STIFFNESS = 7.0, 0.5  # N m / rad, geometric taper
ROOT_DAMPING, TIP_DAMPING = 0.35, 0.03
SLIDE_STIFFNESS = 2500.0  # N / m
SLIDE_RANGE = 0.018  # m of compression per joint
USER_TORSO_X = 0.40  # m in front of the trunk axis
USER_TORSO_RADIUS = 0.14
USER_TORSO_Z = (0.35, 1.05)  # capsule end points (z)
USER_HEAD = (0.40, 0.0, 1.27, 0.11)  # x, y, z, radius
# Contact pairs: the user's torso with the last CONTACT_SEGMENTS segments only. Measured with contact
# off over every held and ramped command in {0, .35, .7, 1}^4 and the whole library, the proximal five
# segments stay >= 5 cm from the torso and every point of the trunk >= 33 cm from the head, so the
# pruned pairs could never touch; tests/sim/test_trunk.py checks it. 5 pairs instead of 20 (2 user geoms x
# 10 segments) cut MJX's collision and constraint work (its cost grows with the number of pairs,
# touching or not).
CONTACT_SEGMENTS = 5

DEFAULT_PATH = asset("trunk.xml")


@dataclasses.dataclass(frozen=True)
class TrunkParams:
    """Every named parameter of the trunk (SPEC section 9); the defaults are the shipped, hand-tuned trunk.

    Lengths in metres, stiffness in N m/rad (hinges) or N/m (slides), damping in N m s/rad or N s/m, force in N,
    density in kg/m^3, ``hinge_range`` in degrees, ``delay`` in seconds. Root and tip values are interpolated
    geometrically along the chain (a taper). ``delay`` holds every tendon command back by that time (MuJoCo's
    actuator delay); 0 adds nothing to the model.
    """

    segments: int = NUM_SEGMENTS
    length: float = TRUNK_LENGTH
    base_radius: float = BASE_RADIUS
    tip_radius: float = TIP_RADIUS
    routing_root: float = BASE_RADIUS  # tendon routing radius at the root (moment arm of a pull)
    routing_tip: float = TIP_RADIUS
    segment_taper: float = 0.45  # the tip segment is this much shorter than the root one (fraction)
    stiffness_root: float = ROOT_STIFFNESS
    stiffness_tip: float = TIP_STIFFNESS
    damping_root: float = ROOT_DAMPING
    damping_tip: float = TIP_DAMPING
    tendon_force: float = MAX_TENDON_FORCE  # N at u = 1
    slide_stiffness: float = SLIDE_STIFFNESS
    slide_damping: float = 8.0
    slide_range: float = SLIDE_RANGE
    density: float = 350.0
    hinge_armature: float = 0.0005
    slide_armature: float = 0.01
    hinge_range: float = 60.0
    delay: float = 0.0

    def __post_init__(self):
        if isinstance(self.segments, bool) or not isinstance(self.segments, int) or not 2 <= self.segments <= 64:
            raise ValueError(f"TrunkParams.segments must be an integer in [2, 64], got {self.segments!r}")
        for f in dataclasses.fields(self)[1:]:
            value = getattr(self, f.name)
            low_ok = value >= 0 if f.name in NON_NEGATIVE else value > 0
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or not low_ok:
                bound = ">= 0" if f.name in NON_NEGATIVE else "> 0"
                raise ValueError(f"TrunkParams.{f.name} must be a finite number {bound}, got {value!r}")
        if not self.segment_taper < 1:
            raise ValueError(f"TrunkParams.segment_taper must be < 1, got {self.segment_taper!r}")
        if not self.hinge_range <= 180:
            raise ValueError(f"TrunkParams.hinge_range must be <= 180 degrees, got {self.hinge_range!r}")

    def replace(self, **changes) -> TrunkParams:
        return dataclasses.replace(self, **changes)


NON_NEGATIVE = ("segment_taper", "hinge_armature", "slide_armature", "slide_damping", "delay")
PARAMETER_NAMES = tuple(f.name for f in dataclasses.fields(TrunkParams))


def load_config(path: str | Path) -> TrunkParams:
    """The :class:`TrunkParams` a TOML file describes: top-level ``name = value`` lines (or a ``[trunk]`` table), any
    subset of :data:`PARAMETER_NAMES`; the others keep their defaults. Unknown names are refused, naming the valid."""
    data = read_toml(path, "trunk description")
    return from_mapping(data.get("trunk", data), source=str(path))


def from_mapping(data: dict, *, source: str = "trunk description") -> TrunkParams:
    """:class:`TrunkParams` from ``{name: value}``; unknown names are refused."""
    unknown = sorted(set(data) - set(PARAMETER_NAMES))
    if unknown:
        raise ValueError(f"{source}: unknown trunk parameters {unknown}; valid: {', '.join(PARAMETER_NAMES)}")
    values = {
        k: float(v) if k != "segments" and isinstance(v, int) and not isinstance(v, bool) else v
        for k, v in data.items()
    }
    return TrunkParams(**values)


def to_mapping(params: TrunkParams) -> dict:
    return dataclasses.asdict(params)


def to_toml(params: TrunkParams) -> str:
    """The TOML text of ``params`` (what :func:`load_config` reads back)."""
    return "".join(f"{k} = {v!r}\n" for k, v in to_mapping(params).items())


def _taper(a: float, b: float, i: int, n: int) -> float:
    """Geometric interpolation from a (root) to b (tip) at joint i of n."""
    return a * (b / a) ** (i / max(n - 1, 1))


def _g(x: float) -> str:
    """A number as MJCF text: integers without a point, other values in full precision."""
    x = float(x)
    return str(int(x)) if x.is_integer() else repr(x)


def segment_lengths(n: int = NUM_SEGMENTS, params: TrunkParams | None = None) -> list[float]:
    p = params or TrunkParams(segments=n)
    w = [1.0 - p.segment_taper * i / (n - 1) for i in range(n)]  # proximal segments longer
    s = sum(w)
    return [p.length * x / s for x in w]


def build_xml(
    n: int | None = None,
    contact: bool = True,
    contact_segments: int = CONTACT_SEGMENTS,
    *,
    params: TrunkParams | None = None,
    exact: bool = False,
) -> str:
    """MJCF text of the trunk ``params`` describes (default: the shipped trunk; ``n`` overrides its segments);
    contact pairs of the user's torso with the last ``contact_segments`` segments (none with ``contact=False``).
    ``exact``: hinge stiffness and damping in full precision (a fitted trunk), not the shipped file's 4 decimals."""
    p = params or TrunkParams()
    if n is not None:
        p = p.replace(segments=n)
    n = p.segments
    contact_segments = min(contact_segments, n)
    fmt = repr if exact else (lambda v: f"{v:.4f}")
    lengths = segment_lengths(n, p)
    lines = [
        '<mujoco model="elephant_trunk">',
        "  <!-- Generated by python -m jgrounding.sim.model; do not edit by hand. -->",
        f'  <option timestep="{TIMESTEP:.8f}" integrator="implicitfast" iterations="4" ls_iterations="6"'
        ' cone="pyramidal">',
        '    <flag warmstart="disable"/>',
        "  </option>",
        "  <default>",
        # No geom collides by default: the only contacts are the explicit <pair>s below.
        f'    <geom contype="0" conaffinity="0" friction="0.6 0.005 0.0001" solref="0.02 1" density="{_g(p.density)}"/>',
        "  </default>",
        '  <visual><global offwidth="640" offheight="480"/></visual>',
        "  <asset>",
        '    <texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.82 0.82" rgb2="0.72 0.72 0.72"'
        ' width="256" height="256"/>',
        '    <material name="floor" texture="grid" texrepeat="8 8"/>',
        '    <material name="skin" rgba="0.55 0.55 0.6 1"/>',
        '    <material name="user" rgba="0.95 0.75 0.55 0.55"/>',
        "  </asset>",
        "  <worldbody>",
        '    <light pos="0.3 -0.8 2.4" dir="-0.1 0.4 -1" diffuse="0.9 0.9 0.9"/>',
        '    <geom name="floor" type="plane" size="2 2 0.01" material="floor" contype="0" conaffinity="0"/>',
        f'    <geom name="head" type="sphere" size="0.12" pos="-0.05 0 {BASE_HEIGHT + 0.08:.3f}"'
        ' rgba="0.5 0.5 0.55 1" contype="0" conaffinity="0"/>',
        # The user is a static body so that a touch sensor over its volume reports contact force.
        '    <body name="user" pos="0 0 0">',
        f'      <geom name="user_torso" type="capsule" fromto="{USER_TORSO_X} 0 {USER_TORSO_Z[0]} '
        f'{USER_TORSO_X} 0 {USER_TORSO_Z[1]}" size="{USER_TORSO_RADIUS}" material="user"/>',
        f'      <geom name="user_head" type="sphere" pos="{USER_HEAD[0]} {USER_HEAD[1]} {USER_HEAD[2]}"'
        f' size="{USER_HEAD[3]}" material="user"/>',
        f'      <site name="user_volume" type="box" pos="{USER_TORSO_X} 0 0.85" size="0.3 0.3 0.6" rgba="0 0 0 0"/>',
        "    </body>",
    ]
    indent = "    "
    z = BASE_HEIGHT
    for i in range(n):
        L = lengths[i]
        r = _taper(p.base_radius, p.tip_radius, i, n)
        k = fmt(_taper(p.stiffness_root, p.stiffness_tip, i, n))
        d = fmt(_taper(p.damping_root, p.damping_tip, i, n))
        hinge = f'range="-{_g(p.hinge_range)} {_g(p.hinge_range)}" armature="{_g(p.hinge_armature)}"'
        pos = f"0 0 {z:.4f}" if i == 0 else f"0 0 {-lengths[i - 1]:.4f}"
        lines.append(f'{indent}<body name="seg{i}" pos="{pos}">')
        lines.append(f'{indent}  <joint name="bx{i}" type="hinge" axis="1 0 0" stiffness="{k}" damping="{d}" {hinge}/>')
        lines.append(f'{indent}  <joint name="by{i}" type="hinge" axis="0 1 0" stiffness="{k}" damping="{d}" {hinge}/>')
        lines.append(
            f'{indent}  <joint name="sl{i}" type="slide" axis="0 0 1" stiffness="{float(p.slide_stiffness)!r}"'
            f' damping="{_g(p.slide_damping)}" range="0 {float(p.slide_range)!r}" limited="true"'
            f' armature="{_g(p.slide_armature)}"/>'
        )
        lines.append(
            f'{indent}  <geom name="g{i}" type="capsule" fromto="0 0 0 0 0 {-L:.4f}" size="{r:.4f}" material="skin"/>'
        )
        lines.append(f'{indent}  <site name="s{i}" pos="0 0 0" size="0.005"/>')
        indent += "  "
    lines.append(f'{indent}<site name="tip" pos="0 0 {-lengths[-1]:.4f}" size="0.008"/>')
    for i in reversed(range(n)):
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines.append("  </worldbody>")
    if contact:
        # Contact pruning: only the distal segments can reach the user's torso, and nothing reaches the
        # head (see CONTACT_SEGMENTS); the pairs carry the same friction / solref as the geoms.
        lines.append("  <contact>")
        for i in range(n - contact_segments, n):
            lines.append(
                f'    <pair geom1="user_torso" geom2="g{i}" condim="3" friction="0.6 0.6 0.005 0.0001 0.0001"'
                ' solref="0.02 1"/>'
            )
        lines.append("  </contact>")
    # Fixed tendons. A positive rotation about +y swings the hanging chain toward -x, about +x toward +y.
    # Tendon j shortens when the trunk bends toward side j; all tendons shorten when the slides
    # compress (slide q > 0 means compression here: its axis is +z, i.e. up the trunk).
    sides = [("t0", "by", +1), ("t1", "bx", -1), ("t2", "by", -1), ("t3", "bx", +1)]
    lines.append("  <tendon>")
    for name, axis, sign in sides:
        lines.append(f'    <fixed name="{name}">')
        for i in range(n):
            r = _taper(p.routing_root, p.routing_tip, i, n)
            lines.append(f'      <joint joint="{axis}{i}" coef="{sign * r:.5f}"/>')
            lines.append(f'      <joint joint="sl{i}" coef="-1"/>')
        lines.append("    </fixed>")
    lines.append("  </tendon>")
    # A command delay: MuJoCo keeps each motor's recent commands (nsample of them, linearly interpolated) and
    # applies the one of ``delay`` seconds ago; before time 0 the command was 0 (at rest).
    delay = f' nsample="{math.ceil(p.delay / TIMESTEP) + 2}" interp="linear" delay="{p.delay!r}"' if p.delay else ""
    lines.append("  <actuator>")
    for name, _, _ in sides:
        lines.append(
            f'    <motor name="m_{name}" tendon="{name}" gear="{-float(p.tendon_force)!r}" ctrlrange="0 1"'
            f' ctrllimited="true"{delay}/>'
        )
    lines.append("  </actuator>")
    # Sensors read by the native rollout (mujoco.rollout returns sensordata): the backbone (segment
    # origins + tip), tendon lengths and the normal force on the user (touch over the user volume).
    lines.append("  <sensor>")
    for i in range(n):
        lines.append(f'    <framepos name="p{i}" objtype="body" objname="seg{i}"/>')
    lines.append('    <framepos name="ptip" objtype="site" objname="tip"/>')
    for name, _, _ in sides:
        lines.append(f'    <tendonpos name="len_{name}" tendon="{name}"/>')
    lines.append('    <touch name="user_touch" site="user_volume"/>')
    lines.append("  </sensor>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"
