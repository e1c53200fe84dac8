"""One decision path from a response to the trunk: the :class:`Responder` every front end calls.

A response (a text, or an (intent, intensity) tuple) becomes an :class:`Outcome` in four steps, the same for the
CLI, the interactive loop, the server and its 30 Hz stream:

1. grounding (:func:`jgrounding.semantics.ground`) of a text;
2. the snap onto the tuples the checkpoint knows (:func:`snap`; a lab's checkpoint covers only the tuples it
   recorded): another intensity of a learned intent moves to the nearest learned one; an intent the checkpoint
   never learned is named and is not confident;
3. the decision (:class:`Decision`): a grounding that is not confident holds still, with its reason, unless
   forced (the act/hold decision of :mod:`jgrounding.semantics.decision` made it: a text that calls for no motion,
   ``grounding.no_motion`` naming why, or one below its kind of text's threshold); a tuple given directly always
   moves. A held text shows :meth:`Decision.message` first and its tuple only after it, as :attr:`Decision.nearest`;
4. the trajectory: sampled by the public sampler (:func:`jgrounding.policy.sampling.sample`, the safety gate),
   or, when holding still, the current command held through the same gate (:meth:`Responder.hold`).

The Responder also owns the warm-up (:meth:`Responder.warm`) and what the model is (:attr:`Responder.info`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path
from typing import Any

import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, SampleConfig
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENSITIES, INTENTS


def _names(tuples) -> str:
    return ", ".join(f"{INTENTS[m]}/{INTENSITIES[z]}" for m, z in sorted(tuples))


def snap(g: Grounding, tuples, checkpoint) -> tuple[Grounding, str | None]:
    """``(grounding, note)``: ``g`` moved onto ``tuples`` (the (intent, intensity) index pairs checkpoint
    ``checkpoint`` was trained on; None: every tuple), and what was changed (None: nothing).

    The same intent at another intensity: the recorded intensity nearest to the asked one (the lower on a tie)
    replaces it and the grounding stays as confident as it was. An intent the checkpoint never learned: the
    learned intent with the highest score in ``g.scores`` (the first learned one when the backend gives no
    scores) at its intensity nearest to the asked one, ``confident=False``: the text asked for something this
    model cannot do, so the trunk holds still unless forced.
    """
    if tuples is None or (g.intent_index, g.intensity_index) in tuples:
        return g, None
    asked = f"({g.intent}, {g.intensity})"
    same = sorted((abs(z - g.intensity_index), z) for m, z in tuples if m == g.intent_index)
    if same:
        z = same[0][1]
        note = (
            f"the text asked for {asked}; checkpoint {checkpoint} learned {g.intent} only at "
            f"{', '.join(INTENSITIES[b] for _, b in sorted(same, key=lambda s: s[1]))}: using the nearest, "
            f"({g.intent}, {INTENSITIES[z]})"
        )
        return dataclasses.replace(g, intensity=INTENSITIES[z]), note
    intents = sorted({m for m, _ in tuples})
    scores = list(g.scores) if len(g.scores) == len(INTENTS) else None
    m = max(intents, key=lambda i: scores[i]) if scores else intents[0]
    z = min((abs(b - g.intensity_index), b) for a, b in tuples if a == m)[1]
    score = f" (score {scores[m]:.2f})" if scores else ""
    note = (
        f"the text asked for {asked}, outside the tuples checkpoint {checkpoint} was trained on "
        f"({_names(tuples)}); its nearest is ({INTENTS[m]}, {INTENSITIES[z]}){score}"
    )
    confidence = float(scores[m]) if scores else 0.0
    reason = (
        g.reason
        if g.no_motion
        else f"asked for {asked}, which this checkpoint never learned; it knows {_names(tuples)}"
    )
    snapped = dataclasses.replace(
        g, intent=INTENTS[m], intensity=INTENSITIES[z], confidence=confidence, confident=False, reason=reason
    )
    return snapped, note


def held(current) -> str:
    """What the trunk keeps while holding still at ``current`` (``"rest"``, None or ``(N_u,)``), for a person."""
    start = safety.current_command(safety.REST if current is None else current, np.size(current) or 1)
    if current is None or isinstance(current, str) or not start.any():
        return "the trunk stays at rest (every tendon command 0)"
    return f"the trunk keeps its current command ({', '.join(f'{v:.2f}' for v in start)})"


@dataclasses.dataclass(frozen=True)
class Decision:
    """Whether the trunk moves for one response, and on which tuple."""

    intent: Any  # a name (from a text), or the intent(s) as given: a name, an index or a list of them
    intensity: Any  # likewise
    grounding: Grounding | None = None  # the text's grounding on the checkpoint's tuples; None: a tuple given
    note: str | None = None  # what the snap onto the checkpoint's tuples changed (None: nothing)
    hold: bool = False  # hold still: the grounding is not confident and the response was not forced
    reason: str = ""  # why the grounding is not acted on ("" when it is confident)

    @property
    def forced(self) -> bool:
        """Driven although the grounding is not confident (``force``)."""
        return bool(self.reason) and not self.hold

    def message(self, current=safety.REST) -> str | None:
        """``"holding still: <reason>; <what the trunk keeps>"`` when holding still at ``current``, else None: what
        every front end shows first for a held text."""
        return f"holding still: {self.reason}; {held(current)}" if self.hold else None

    @property
    def nearest(self) -> str | None:
        """``"nearest: (intent, intensity), p = 0.55"`` for a held text: the tuple it was not acted on, which the
        front ends show only after :meth:`message`, in small print; None when not holding a text."""
        if not self.hold or self.grounding is None:
            return None
        return f"nearest: ({self.intent}, {self.intensity}), p = {self.grounding.confidence:.2f}"


@dataclasses.dataclass(frozen=True)
class Outcome:
    """A decision and the trajectory that carries it out."""

    decision: Decision
    u: np.ndarray  # float32, shaped as jg.sample returns it: (150, N_u), (K, 150, N_u) or (N, K, 150, N_u)
    message: str | None = None  # Decision.message at the current command, when holding still
    screened: Any = None  # sampling.Screened of a screened call (candidates, rejected, ...), else None


class Responder:
    """The shipped model (or a lab's ``checkpoint``) and the grounding behind one decision path.

    ``backend``: the grounding backend (:data:`jgrounding.semantics.BACKENDS`). The model is restored on first
    use (:attr:`model`; refusals are ``ValueError`` s naming the checkpoint); :meth:`warm` loads and compiles
    what a server answers most.
    """

    def __init__(
        self,
        checkpoint=None,
        *,
        allow_library_mismatch: bool = False,
        backend: str = "embedded",
        trunk: str | None = None,
    ):
        if checkpoint is not None and not isinstance(checkpoint, (str, Path)):
            raise TypeError(f"checkpoint must be a directory path (str or pathlib.Path), got {type(checkpoint)}")
        self.checkpoint = None if checkpoint is None else str(checkpoint)
        self.allow_library_mismatch = bool(allow_library_mismatch)
        self.backend = backend
        self.warmed = False
        from jgrounding import sim

        self.trunk = sim.resolve_trunk(trunk)  # what screening simulates (None: the shipped trunk)

    @functools.cached_property
    def model(self):
        """The :class:`jgrounding.policy.sampling.Model` of the checkpoint (the shipped default RF for None)."""
        from jgrounding.policy import sampling

        return sampling.model(self.checkpoint, self.allow_library_mismatch)

    @property
    def num_tendons(self) -> int:
        return self.model.trained.num_tendons

    @property
    def tuples(self) -> frozenset | None:
        """The (intent, intensity) index pairs the model knows (None: all 64)."""
        return self.model.covered

    @property
    def inpaints(self) -> bool:
        """Whether the model samples from a given start (start-conditioned), else streams blend in."""
        generator = self.model.trained.spec.generator
        if hasattr(type(generator), "inpaints"):  # the generator protocol's declared ability
            return bool(generator.inpaints)
        from jgrounding.generators import methods  # until every generator declares it

        try:
            methods.check_start_conditioning(self.model.trained.method)
            return True
        except ValueError:
            return False

    @functools.cached_property
    def info(self) -> dict:
        """What is served: package, checkpoint, method, library version and digests, sizes."""
        import jgrounding as jg
        from jgrounding.policy import sampling
        from jgrounding.training import checkpoints

        path = Path(self.checkpoint) if self.checkpoint else sampling.DEFAULT_CHECKPOINT
        meta = checkpoints.read_meta(path)
        shipped = json.loads(sampling.SHIPPED.read_text()) if sampling.SHIPPED.exists() else {}
        return {
            "package_version": jg.__version__,
            "checkpoint": path.name if self.checkpoint is None else str(path),
            "shipped": self.checkpoint is None,
            "few_step_checkpoints": [dict(e) for e in shipped.get("few_step", [])] if self.checkpoint is None else [],
            "method": self.model.trained.method,
            "library_version": meta.get("library_version", "unknown"),
            "library_sha256": (meta.get("library_sha256") or "")[:12],
            "params_sha256": (meta.get("params_sha256") or "")[:12],
            "train_step": meta.get("step"),
            "num_tendons": self.num_tendons,
            "num_controls": self.model.trained.num_controls,
        }

    # -- the decision --

    def decide(self, text: str | None = None, *, intent=None, intensity=None, force: bool = False) -> Decision:
        """The decision for a ``text`` (grounded, snapped onto the model's tuples) or a given ``intent`` and
        ``intensity`` (names, indices or lists; intensity default ``moderate``; always moves). ``force``: drive
        a grounding that is not confident."""
        if text is None:
            if intent is None:
                raise ValueError(f"give a text or an intent (one of {', '.join(INTENTS)})")
            return Decision(intent, "moderate" if intensity is None else intensity)
        from jgrounding.semantics import ground

        g, note = snap(ground(text, backend=self.backend), self.tuples, self.checkpoint)
        reason = "" if g.confident else (g.reason or "low confidence")
        return Decision(g.intent, g.intensity, g, note, hold=bool(reason) and not force, reason=reason)

    # -- the trajectory --

    def hold(self, current=safety.REST, num_samples: int = 1) -> np.ndarray:
        """The current command held for the whole response, through the gate: ``(150, N_u)`` (one sample) or
        ``(K, 150, N_u)``, shaped as a sample of the model would be. ``current`` None holds rest."""
        n = self.num_tendons
        start = safety.current_command(safety.REST if current is None else current, n)
        u = safety.emit(np.broadcast_to(start, (num_samples, NUM_STEPS, n)), num_channels=n, current=start)
        return u[0] if num_samples == 1 else u

    def trajectory(self, key, intent, intensity, num_samples: int = 1, **options) -> np.ndarray:
        """:func:`jgrounding.policy.sampling.sample` of this model; ``options``: ``sampler``, ``steps``,
        ``current``, ``start_conditioned``."""
        from jgrounding.policy import sampling

        return sampling.sample(
            key,
            intent,
            intensity,
            num_samples,
            checkpoint=self.checkpoint,
            allow_library_mismatch=self.allow_library_mismatch,
            **options,
        )

    def act(
        self, key, decision: Decision, num_samples: int = 1, *, current=safety.REST, screen: bool = False, **options
    ) -> Outcome:
        """Carry out ``decision``: hold still at ``current`` or sample ``num_samples`` trajectories blended in
        from it (``screen``: only candidates the simulated trunk finds feasible; ``options`` as
        :meth:`trajectory`)."""
        if decision.hold:
            return Outcome(decision, self.hold(current, num_samples), decision.message(current))
        if screen:
            from jgrounding.policy import sampling

            res = sampling.screened(
                key,
                decision.intent,
                decision.intensity,
                num_samples,
                checkpoint=self.checkpoint,
                allow_library_mismatch=self.allow_library_mismatch,
                current=current,
                trunk=self.trunk,
                **options,
            )
            return Outcome(decision, res.u, screened=res)
        u = self.trajectory(key, decision.intent, decision.intensity, num_samples, current=current, **options)
        return Outcome(decision, np.asarray(u, np.float32))

    def respond(self, key, text: str | None = None, *, intent=None, intensity=None, force=False, **act) -> Outcome:
        """:meth:`decide` then :meth:`act` (``act``: ``num_samples``, ``current``, ``screen``, ``sampler``,
        ``steps``, ``start_conditioned``)."""
        return self.act(key, self.decide(text, intent=intent, intensity=intensity, force=force), **act)

    # -- start-up --

    def warm(self) -> Responder:
        """Load and compile what a server answers most: the grounding (every encoder length), the hold, and
        single samples blended and start-conditioned (and the few-step model for the shipped one). Once."""
        if self.warmed:
            return self
        import jax

        from jgrounding.semantics import encoder

        self.decide("User seems sad; respond calmly")
        for bucket in encoder.BUCKETS:  # one encoder program per padded text length
            self.decide(" ".join(["calm"] * max(1, bucket - 3)))
        mid = np.full(self.num_tendons, 0.3, np.float32)
        self.hold(mid)
        m, z = min(self.tuples) if self.tuples else (0, 0)
        for steps in sorted({SampleConfig.steps, 2} if self.checkpoint is None else {SampleConfig.steps}):
            for start in {False, self.inpaints}:
                self.trajectory(jax.random.key(0), m, z, 1, steps=steps, current=mid, start_conditioned=start)
            self.trajectory(jax.random.key(0), m, z, 1, steps=steps, current=safety.REST)
        self.warmed = True
        return self
