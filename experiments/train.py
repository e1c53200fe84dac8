"""Train one method and save an orbax checkpoint (resumable):

    python -m experiments.train --method tuple_spline_rf --steps 10000 --seeds 0 --out jgrounding/assets/checkpoints/tuple_spline_rf

``--library my_library.npz`` trains on another library, e.g. one imported from recordings
(``python -m jgrounding.library import DIR --out my_library.npz``; docs/own_data.md); the number of
tendons N_u comes from it, and the checkpoint records the library's path, sha256 and tuples, so
``jg.sample(..., checkpoint=OUT)`` refuses a changed library or a tuple it never saw.

A run killed at any point resumes from its last chunk checkpoint (``--out``) and ends with the same
parameters as an uninterrupted run. ``--devices N`` (0 = all) splits the seeds over a device mesh; a
multi-host job sets ``JAX_COORDINATOR_ADDRESS/JAX_NUM_PROCESSES/JAX_PROCESS_ID`` (docs/distributed.md)
and only process 0 writes checkpoints.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp

from jgrounding import config as configs
from jgrounding import library, load_library, semantics, training
from jgrounding.generators import methods
from jgrounding.training import checkpoints, distributed, trainer
from jgrounding.vocabulary import INTENSITIES, INTENTS


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Train one Table II method.")
    p.add_argument("--method", choices=methods.ALL_METHODS, default="tuple_spline_rf")
    configs.add_arguments(p, "train.ema_decay=0.999")
    p.add_argument("--steps", type=int, help=f"= --set train.steps=... (default {training.TrainConfig.steps})")
    p.add_argument("--chunk", type=int, help=f"= --set train.chunk=... (default {training.TrainConfig.chunk})")
    p.add_argument("--seeds", default="0", help="comma-separated seeds, e.g. 0,1,2,3,4")
    p.add_argument("--out", required=True, help="checkpoint directory (resumes if it holds a partial run)")
    p.add_argument("--num-controls", type=int, default=4)
    p.add_argument("--devices", type=int, default=1, help="split the seeds over this many devices (0 = all)")
    p.add_argument("--library", help="library .npz to train on (default: the shipped jgrounding/assets/library.npz)")
    p.add_argument(
        "--data",
        choices=("train", "all"),
        default="train",
        help="train: the 192 training pairs (Table II's protocol); all: every library pair, train and held out "
        "(the shipped model; the evaluation set is never trained on)",
    )
    opts = p.add_argument_group("generator options (off by default: the paper's Table I)")
    opts.add_argument("--ema-decay", type=float, help="= --set train.ema_decay=...: ship an EMA (0 = off)")
    opts.add_argument("--time-sampler", help="= --set train.time_sampler=...: uniform, logit_normal, beta")
    opts.add_argument("--condition-dropout", type=float, help="= --set train.condition_dropout=... (for guidance)")
    opts.add_argument("--guidance", type=float, help="= --set sample.guidance=...: the checkpoint's sampling default")
    opts.add_argument(
        "--reflow-from",
        help="train a 2-rectified flow from this RF checkpoint's own samples (seeds of --seeds; not resumable)",
    )
    opts.add_argument("--reflow-pairs", type=int, default=64, help="teacher pairs per training example")
    args = p.parse_args(argv)
    try:
        seeds = tuple(int(s) for s in args.seeds.split(","))
    except ValueError:
        seeds = ()
    if not seeds or len(set(seeds)) != len(seeds) or min(seeds) < 0:
        p.error(f"--seeds must be distinct non-negative integers separated by commas, e.g. 0,1,2; got {args.seeds!r}")
    flags = {  # the flags kept from before the composed config: each is one override
        "steps": "train.steps",
        "chunk": "train.chunk",
        "ema_decay": "train.ema_decay",
        "time_sampler": "train.time_sampler",
        "condition_dropout": "train.condition_dropout",
        "guidance": "sample.guidance",
    }
    overrides = [f"{field}={getattr(args, flag)}" for flag, field in flags.items() if getattr(args, flag) is not None]
    try:
        full = configs.get(args.config, [*overrides, *args.set])
        config, sample_cfg, model_cfg = full.train, full.sample, full.model
        methods.check_options(args.method, config)
    except ValueError as e:
        p.error(str(e))
    distributed.initialize()  # multi-host only; a no-op on one machine
    if args.devices < 0 or args.devices > jax.device_count():
        p.error(f"--devices must be in 0..{jax.device_count()} (0 = all), got {args.devices}")
    mesh = distributed.make_mesh(args.devices or None) if args.devices != 1 else None
    writer = jax.process_index() == 0
    try:
        lib = load_library(args.library)
    except (OSError, ValueError) as e:
        p.error(f"--library: {e}")
    if args.data == "all":
        lib = library.with_all_pairs(lib)
    num_tendons = int(lib.train.u.shape[-1])
    text_emb = None
    if methods.spec(args.method).condition.needs_text:
        texts = [t for row in lib.train.texts for t in row]
        text_emb = semantics.embed(texts).reshape(len(lib.train), -1, 384)
    tuples = sorted({(int(m), int(z)) for m, z in zip(lib.train.intent, lib.train.intensity)})
    meta = {
        "method": args.method,
        "seeds": list(seeds),
        "num_controls": args.num_controls,
        "model": dataclasses.asdict(model_cfg),
        "config": dataclasses.asdict(config),
        "sample": dataclasses.asdict(sample_cfg),
        "library_sha256": library.file_hash(lib.path),
        "library_version": lib.meta.get("library_version", "1 (unversioned)"),
        "data": args.data,
        "run_config": configs.to_dict(full),  # the whole composed config (named entry + overrides)
    }
    if args.library:  # the shipped library's checkpoints keep their old metadata
        meta.update(
            library_path=str(Path(lib.path).resolve()),
            num_tendons=num_tendons,
            tuples=[f"{INTENTS[m]}/{INTENSITIES[z]}" for m, z in tuples],
        )
    run_dir = args.out + ".run"
    if args.reflow_from:
        return reflow(args, lib, config, meta, seeds, writer)

    def template():
        graphdef, params = methods.init(args.method, seeds, args.num_controls, num_tendons, model_cfg)
        keys = jnp.stack([jax.random.fold_in(jax.random.key(s), 1) for s in seeds])
        return jax.vmap(lambda pp, k: training.init_state(pp, k, config))(params, keys)

    def to_tree(states):
        return dataclasses.replace(states, key=jax.random.key_data(states.key))

    initial = None
    try:  # resume only the same run: method, seeds, P, library and optimizer settings must match
        tmpl = to_tree(template())
        tree, m = checkpoints.restore(
            run_dir, tmpl, expect={k: meta[k] for k in ("method", "seeds", "num_controls", "library_sha256")}
        )
        fixed = {k: v for k, v in meta["config"].items() if k not in ("steps", "chunk")}
        stored = {k: m.get("config", {}).get(k) for k in fixed}
        if stored != fixed:
            raise ValueError(f"checkpoint {run_dir} was trained with {stored}, this run asks for {fixed}")
        if int(m["step"]) > args.steps:
            raise ValueError(f"checkpoint {run_dir} is at step {m['step']}, beyond --steps {args.steps}")
        initial = dataclasses.replace(tree, key=jax.random.wrap_key_data(jnp.asarray(tree.key)))
        print(f"resuming {args.method} from step {int(m['step'])}")
    except FileNotFoundError:
        pass
    except ValueError as e:
        raise SystemExit(f"error: cannot resume: {e}\n(delete {run_dir} to start this run afresh)")

    def on_chunk(states, done):
        if writer:
            checkpoints.save(run_dir, to_tree(states), {**meta, "step": done})

    trained = trainer.fit(
        args.method,
        lib,
        seeds,
        config,
        text_emb=text_emb,
        num_controls=args.num_controls,
        initial_states=initial,
        on_chunk=on_chunk,
        mesh=mesh,
        model=model_cfg,
    )
    trained = dataclasses.replace(trained, sample_config=sample_cfg)  # the sampling default it records
    final = jax.tree.map(lambda x: x[:1], trained.params) if len(seeds) > 1 else trained.params
    if writer:
        checkpoints.save(
            args.out, final, {**meta, **checkpoints.meta_of(trained), "seeds": [seeds[0]], "step": args.steps}
        )
        import shutil

        shutil.rmtree(run_dir, ignore_errors=True)  # the run finished: its resume state is no longer needed
    print(f"saved {args.out} (seed {seeds[0]}); final loss {float(trained.losses[0, -100:].mean()):.4f}")
    return 0


def reflow(args, lib, config, meta, seeds, writer) -> int:
    """2-rectified flow of the checkpoint ``--reflow-from`` (its guidance w is distilled in: the result
    samples with w = 0)."""
    teacher = checkpoints.restore_trained(args.reflow_from, "tuple_spline_rf")
    teacher_meta = checkpoints.read_meta(args.reflow_from)
    w = float(teacher_meta.get("sample", {}).get("guidance", 0.0))
    trained = trainer.reflow(teacher, lib, config, pairs_per_example=args.reflow_pairs, teacher_guidance=w)
    if writer:
        checkpoints.save(
            args.out,
            trained.params,
            {
                **meta,
                **checkpoints.meta_of(trained),
                "step": args.steps,
                "reflow_of": str(args.reflow_from),
                "teacher_guidance": w,
                "reflow_pairs": args.reflow_pairs,
            },
        )
    print(
        f"saved {args.out} (2-rectified flow of {args.reflow_from}, seeds {list(trained.seeds)}); "
        f"final loss {float(trained.losses[0, -100:].mean()):.4f}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
