"""Train one method and save an orbax checkpoint (resumable):

    python -m experiments.train --method tuple_spline_rf --steps 10000 --seeds 0 --out assets/checkpoints/tuple_spline_rf

A run killed at any point resumes from its last chunk checkpoint (``--out``) and ends with the same
parameters as an uninterrupted run.
"""
from __future__ import annotations

import argparse
import dataclasses

import jax
import jax.numpy as jnp

from jgrounding import checkpoints, library, load_library, methods, semantics, training


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Train one Table II method.")
    p.add_argument("--method", choices=methods.METHODS, default="tuple_spline_rf")
    p.add_argument("--steps", type=int, default=training.TrainConfig.steps)
    p.add_argument("--chunk", type=int, default=training.TrainConfig.chunk)
    p.add_argument("--seeds", default="0", help="comma-separated seeds, e.g. 0,1,2,3,4")
    p.add_argument("--out", required=True, help="checkpoint directory (resumes if it holds a partial run)")
    p.add_argument("--num-controls", type=int, default=4)
    args = p.parse_args(argv)
    seeds = tuple(int(s) for s in args.seeds.split(","))
    config = training.TrainConfig(steps=args.steps, chunk=args.chunk)
    lib = load_library()
    text_emb = None
    if methods.spec(args.method).condition == "raw":
        texts = [t for row in lib.train.texts for t in row]
        text_emb = semantics.embed(texts).reshape(len(lib.train), -1, 384)
    meta = {"method": args.method, "seeds": list(seeds), "num_controls": args.num_controls,
            "config": dataclasses.asdict(config), "library_sha256": library.file_hash()}
    run_dir = args.out + ".run"

    def template():
        graphdef, params = methods.init(args.method, seeds, args.num_controls)
        keys = jnp.stack([jax.random.fold_in(jax.random.key(s), 1) for s in seeds])
        return jax.vmap(lambda pp, k: training.init_state(pp, k, config))(params, keys)

    def to_tree(states):
        return dataclasses.replace(states, key=jax.random.key_data(states.key))

    initial = None
    try:
        tmpl = to_tree(template())
        tree, m = checkpoints.restore(run_dir, tmpl, expect={k: meta[k] for k in ("method", "seeds", "num_controls")})
        initial = dataclasses.replace(tree, key=jax.random.wrap_key_data(jnp.asarray(tree.key)))
        print(f"resuming {args.method} from step {int(m['step'])}")
    except FileNotFoundError:
        pass

    def on_chunk(states, done):
        checkpoints.save(run_dir, to_tree(states), {**meta, "step": done})

    trained = methods.train(args.method, lib, seeds, config, text_emb=text_emb, num_controls=args.num_controls,
                            initial_states=initial, on_chunk=on_chunk)
    final = jax.tree.map(lambda x: x[:1], trained.params) if len(seeds) > 1 else trained.params
    checkpoints.save(args.out, final, {**meta, "seeds": [seeds[0]], "step": args.steps})
    import shutil

    shutil.rmtree(run_dir, ignore_errors=True)  # the run finished: its resume state is no longer needed
    print(f"saved {args.out} (seed {seeds[0]}); final loss {float(trained.losses[0, -100:].mean()):.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
