"""Fuzzing the boundaries (issue: reliability): sampling path, jg.sample, jg.ground and the CLI.

- >= 10^5 random and adversarial conditions and keys through the compiled sampler of the shipped RF
  model: every output is finite, inside [0, 1] and slew-limited; NaN conditions are refused at the exit.
- ``jg.sample`` with fuzzed arguments: valid ones give safe arrays, invalid ones a ValueError/TypeError
  that names what is accepted.
- fuzzed text through ``jg.ground``: a grounding or a clear ValueError/TypeError, nothing else.
- fuzzed command lines through ``jgrounding.apps.cli.main``: success, or exit 2 with a usage message.
"""

import contextlib
import io
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jgrounding as jg
from jgrounding import safety
from jgrounding.apps import cli
from jgrounding.config import SampleConfig
from jgrounding.evaluation import generate
from jgrounding.generators import flows
from jgrounding.policy import sampling
from jgrounding.vocabulary import INTENSITIES, INTENTS, normalise

BATCH = 2048
FUZZ_BATCHES = 52  # 52 x 2048 = 106,496 conditions, each with its own noise
SAMPLER_CONFIGS = tuple(SampleConfig(s, n) for s, n in (("euler", 50), ("euler", 1), ("midpoint", 4), ("rk4", 2)))
CONDITION_KINDS = ("vocabulary", "direction", "huge", "tiny", "flipped", "zeros", "spikes", "mixed")


@pytest.fixture(scope="module")
def model():
    trained, intent_emb = sampling.load()
    return trained, np.asarray(intent_emb, np.float32)


def _conditions(kind: str, rng: np.random.Generator, emb: np.ndarray, scale: float) -> np.ndarray:
    """``(BATCH, 384)`` finite condition embeddings, |c| <= 1e4: realistic and adversarial."""
    pick = emb[rng.integers(0, len(emb), BATCH)]
    if kind == "vocabulary":
        return pick
    if kind == "direction":  # random directions at a drawn magnitude
        d = rng.normal(size=(BATCH, emb.shape[1]))
        return (scale * d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    if kind == "huge":
        return pick * np.float32(1e4) * rng.choice([-1, 1], (BATCH, 1)).astype(np.float32)
    if kind == "tiny":
        return pick * np.float32(1e-30)
    if kind == "flipped":
        return -pick
    if kind == "zeros":
        return np.zeros_like(pick)
    if kind == "spikes":  # a few coordinates at +-1e4, the rest of a real embedding
        out = pick.copy()
        rows, cols = rng.integers(0, BATCH, 4 * BATCH), rng.integers(0, emb.shape[1], 4 * BATCH)
        out[rows, cols] = rng.choice([-1e4, 1e4], 4 * BATCH)
        return out
    parts = [_conditions(k, rng, emb, scale) for k in CONDITION_KINDS[:-1]]
    which = rng.integers(0, len(parts), BATCH)
    return np.stack(parts)[which, np.arange(BATCH)]


def _key(kind: str, seed: int, words: tuple[int, int]):
    if kind == "typed":
        return sampling.as_key(jax.random.key(seed))
    if kind == "raw":
        return sampling.as_key(jax.random.PRNGKey(seed))
    return sampling.as_key(np.array(words, np.uint32))  # raw key data, extremes included


def _assert_safe(u: np.ndarray) -> None:
    assert np.all(np.isfinite(u)), "non-finite actuation"
    assert u.min() >= safety.ACTUATION_MIN and u.max() <= safety.ACTUATION_MAX, (u.min(), u.max())
    assert np.abs(np.diff(u, axis=-2)).max() <= safety.MAX_SLEW + 1e-6


@pytest.mark.slow
def test_sampling_path_is_safe_for_1e5_fuzzed_conditions_and_keys(model):
    trained, emb = model
    seen = {"conditions": 0, "kinds": set()}
    word = st.sampled_from([0, 1, 2**31, 2**32 - 1]) | st.integers(0, 2**32 - 1)

    @settings(max_examples=FUZZ_BATCHES, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
    @given(
        kind=st.sampled_from(CONDITION_KINDS),
        seed=st.integers(0, 2**32 - 1),
        scale=st.sampled_from([1e-30, 1e-6, 1e-2, 1.0, 10.0, 1e2, 1e3, 1e4]),
        key_kind=st.sampled_from(["typed", "raw", "data"]),
        words=st.tuples(word, word),
        config=st.sampled_from(SAMPLER_CONFIGS),
    )
    def run(kind, seed, scale, key_kind, words, config):
        rng = np.random.default_rng(seed)
        cond = _conditions(kind, rng, emb, scale)
        assert cond.shape == (BATCH, 384) and np.all(np.isfinite(cond)) and np.abs(cond).max() <= 1e4
        intensity = rng.integers(0, 4, BATCH).astype(np.int32)
        fn = generate.generate_fn(trained, config)
        u = np.asarray(fn(trained.params, jnp.asarray(cond), jnp.asarray(intensity), _key(key_kind, seed, words)[None]))
        assert u.shape == (1, BATCH, 150, 4)
        _assert_safe(u)
        seen["conditions"] += BATCH
        seen["kinds"].add(kind)

    run()
    assert seen["conditions"] >= 100_000
    assert len(seen["kinds"]) >= 6  # the adversarial kinds were all but certainly drawn


@settings(max_examples=20, deadline=None, database=None)
@given(
    rows=st.lists(st.integers(0, 31), min_size=1, max_size=8, unique=True),
    value=st.sampled_from([np.nan, np.inf, -np.inf]),
    seed=st.integers(0, 2**32 - 1),
)
def test_non_finite_conditions_are_never_emitted(rows, value, seed):
    trained, emb = sampling.load()
    cond = np.array(emb[np.arange(32) % 16], np.float32)
    cond[rows, seed % 384] = value
    fn = generate.generate_fn(trained, SampleConfig())
    u = np.asarray(fn(trained.params, jnp.asarray(cond), jnp.zeros(32, jnp.int32), jax.random.key(seed)[None]))[0]
    if np.isnan(value):
        assert np.isnan(u[rows]).any()  # propagated, never repaired into something plausible
    if not np.all(np.isfinite(u)):
        with pytest.raises(safety.UnsafeActuationError, match="non-finite"):
            safety.emit(u)
    else:
        _assert_safe(safety.emit(u))
    clean = np.setdiff1d(np.arange(32), rows)
    _assert_safe(safety.emit(u[clean]))  # the other rows are unaffected and safe


# ----------------------------------------------------------------------------- jg.sample arguments


def _name_variants(names):
    return st.sampled_from(names) | st.sampled_from(names).map(lambda s: f"  {s.upper().replace('_', '-')} ")


VALID_INTENT = _name_variants(INTENTS) | st.integers(0, 15) | st.integers(0, 15).map(np.int64)
VALID_INTENSITY = _name_variants(INTENSITIES) | st.integers(0, 3) | st.integers(0, 3).map(np.int32)
SEED = st.integers(0, 2**32 - 1)
VALID_KEY = (
    SEED.map(jax.random.key)
    | SEED.map(jax.random.PRNGKey)
    | SEED.map(lambda s: np.array([s, s ^ 0xFFFFFFFF], np.uint32))
)


@settings(max_examples=25, deadline=None, database=None)
@given(
    key=VALID_KEY,
    intent=VALID_INTENT,
    intensity=VALID_INTENSITY,
    num_samples=st.integers(1, 8),
    config=st.sampled_from([("euler", 50), ("rk4", 4), ("midpoint", 2)]),
)
def test_sample_with_valid_fuzzed_arguments_is_safe(key, intent, intensity, num_samples, config):
    u = jg.sample(key, intent, intensity, num_samples=num_samples, sampler=config[0], steps=config[1])
    assert u.dtype == np.float32
    assert u.shape == ((150, 4) if num_samples == 1 else (num_samples, 150, 4))
    _assert_safe(u)


def _not_a(names):
    return lambda v: not (isinstance(v, str) and normalise(v) in names)


JUNK = (
    st.none()
    | st.floats(allow_nan=True)
    | st.binary(max_size=4)
    | st.lists(st.integers(), max_size=2)
    | st.booleans()
    | st.dictionaries(st.text(max_size=2), st.integers(), max_size=1)
)


def _not_indices(n):  # a non-empty list of valid indices is a valid sequence of tuples
    return lambda v: not (isinstance(v, list) and v and all(0 <= i < n for i in v))


BAD = {
    "intent": (
        st.text(max_size=30).filter(_not_a(INTENTS))
        | st.integers().filter(lambda i: not 0 <= i < 16)
        | JUNK.filter(_not_indices(16)),
        "greeting, farewell",
    ),
    "intensity": (
        st.text(max_size=30).filter(_not_a(INTENSITIES))
        | st.integers().filter(lambda i: not 0 <= i < 4)
        | JUNK.filter(_not_indices(4)),
        "subtle, moderate, pronounced, emphatic",
    ),
    "num_samples": (
        st.integers().filter(lambda k: not 1 <= k <= sampling.MAX_SAMPLES)
        | st.text(max_size=3)
        | JUNK
        | st.floats(1, 8),
        f"1..{sampling.MAX_SAMPLES}",
    ),
    "steps": (
        st.integers().filter(lambda s: not 1 <= s <= 1000) | st.text(max_size=3) | JUNK | st.floats(1, 50),
        "1..1000",
    ),
    "sampler": (
        st.text(max_size=10).filter(lambda s: s not in flows.RF_SAMPLERS) | JUNK.filter(lambda v: v is not None),
        "euler, midpoint, rk4",
    ),  # None: the default sampler
    "key": (
        st.integers()
        | st.floats()
        | st.text(max_size=5)
        | st.none()
        | st.binary(max_size=8)
        | st.sampled_from(
            [
                np.zeros(2, np.int32),
                np.zeros(3, np.uint32),
                np.zeros((2, 2), np.uint32),
                np.zeros(2, np.float32),
                jnp.zeros(2, jnp.int32),
            ]
        )
        | SEED.map(lambda s: jax.random.split(jax.random.key(s), 2)),
        "jax.random.key(seed)",
    ),
}


@settings(max_examples=200, deadline=None, database=None)
@given(data=st.data(), field=st.sampled_from(sorted(BAD)))
def test_sample_with_invalid_fuzzed_arguments_names_what_is_accepted(data, field):
    strategy, accepted = BAD[field]
    args = dict(
        key=jax.random.key(0), intent="greeting", intensity="moderate", num_samples=1, sampler="euler", steps=50
    )
    args[field] = data.draw(strategy, label=field)
    with pytest.raises((ValueError, TypeError)) as info:
        jg.sample(args.pop("key"), args.pop("intent"), args.pop("intensity"), **args)
    assert accepted in str(info.value)


# ----------------------------------------------------------------------------- jg.ground text

WORDS = [
    "please",
    "wave",
    "hello",
    "gently",
    "VERY",
    "!!!",
    "hug",
    "no",
    "sad",
    "user",
    "come",
    "here",
    "slowly",
    "rest",
    "point",
    "celebrate",
    "…",
    "🐘",
    "не",
    "好",
    "\u202e",
    "\u200b",
    "\t",
    "\x00",
    "\x1b[31m",
]
TEXT = (
    st.text(max_size=200)
    | st.text(st.characters(max_codepoint=0x1F), max_size=40)  # control characters only
    | st.lists(st.sampled_from(WORDS), max_size=40).map(" ".join)
    | st.builds(lambda s, n: s * n, st.text(min_size=1, max_size=6), st.integers(500, 20_000))  # very long
    | st.builds(
        lambda a, s, b: a + s + b,
        st.text(max_size=10),
        st.text(st.characters(min_codepoint=0xD800, max_codepoint=0xDFFF), min_size=1, max_size=2),
        st.text(max_size=10),
    )  # lone surrogates: not encodable text
    | st.sampled_from(["", " ", "\n\t\r", "\x00"])
)


@settings(max_examples=40, deadline=None, database=None)
@given(text=TEXT | st.none() | st.integers() | st.binary(max_size=10) | st.lists(st.text(max_size=3), max_size=2))
def test_ground_fuzzed_text_gives_a_tuple_or_a_clear_error(text):
    try:
        g = jg.ground(text, backend="embedded")
    except TypeError as e:
        assert not isinstance(text, str) and "text must be a str" in str(e)
        return
    except ValueError as e:
        assert isinstance(text, str) and ("empty" in str(e) or "not valid Unicode" in str(e))
        return
    assert g.intent in INTENTS and g.intensity in INTENSITIES
    assert 0.0 <= g.confidence <= 1.0 and g.backend == "embedded"
    if not g.confident:
        assert g.reason  # a low-confidence grounding says why


# ----------------------------------------------------------------------------- command line

OPTIONS = [
    "--intent",
    "--intensity",
    "--samples",
    "--seed",
    "--sampler",
    "--steps",
    "--backend",
    "--out",
    "--quiet",
    "--jsonl",
    "--no-render",
    "-h",
    "--bogus",
    "-x",
    "--",
    "--samples=2",
    "--steps=0",
    "--intent=nodding",
    "--seed=-1",
    "--out=",
]
VALUES = [
    "greeting",
    "comforting",
    "dancing",
    "subtle",
    "emphatic",
    "EXTREME",
    "euler",
    "rk4",
    "heun",
    "embedded",
    "mllm",
    "0",
    "1",
    "2",
    "4",
    "50",
    "300",
    "-1",
    "1e9",
    "4294967296",
    "nan",
    "",
    " ",
    "x",
    "\udcff",
    "User seems sad; respond calmly",
    "wave hello!!",
    "a" * 5000,
]
TOKEN = st.sampled_from(OPTIONS) | st.sampled_from(VALUES) | st.text(max_size=12)
# Mostly valid command lines (a tuple or a text, plus options), sometimes with one token spliced in.
SUBJECT = st.tuples(st.just("--intent"), st.sampled_from(INTENTS)).map(list) | st.sampled_from(
    ["User seems sad; respond calmly", "wave hello!!", "x", "🐘 ok"]
).map(lambda t: [t])
EXTRA = st.sampled_from(
    [
        ["--intensity", "subtle"],
        ["--samples", "3"],
        ["--samples", "1"],
        ["--seed", "7"],
        ["--sampler", "rk4"],
        ["--steps", "4"],
        ["--jsonl"],
        ["--quiet"],
        ["--backend", "embedded"],
    ]
)
VALID_ARGV = st.builds(lambda a, b: a + [t for x in b for t in x], SUBJECT, st.lists(EXTRA, max_size=3))
SPLICED = st.builds(
    lambda argv, i, t: argv[: i % (len(argv) + 1)] + [t] + argv[i % (len(argv) + 1) :],
    VALID_ARGV,
    st.integers(0, 10),
    TOKEN,
)
ARGV = st.lists(TOKEN, max_size=7) | VALID_ARGV | SPLICED


@settings(max_examples=60, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(argv=ARGV)
def test_cli_fuzzed_arguments_succeed_or_exit_2_with_usage(argv):
    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):
        out, err = io.StringIO(), io.StringIO()
        code = None
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main(["--no-render", "--out", "out"] + argv)
            except SystemExit as e:
                code = e.code
        message = err.getvalue()
        assert "Traceback" not in message + out.getvalue()
        if code == 2:
            assert message.startswith("usage: python -m jgrounding") and "error:" in message
        else:
            assert code == 0, (argv, code, message[-500:])
            if "-h" not in argv:  # a run: its files are there
                written = [p for p in Path(tmp).rglob("samples.npy")]
                assert len(written) == 1
                _assert_safe(np.load(written[0]))
