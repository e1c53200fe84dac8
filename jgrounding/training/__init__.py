"""Training: the compiled loop (AdamW, scan chunks, vmap over seeds), checkpoints and device meshes."""

from jgrounding.training.loop import TrainConfig, TrainState, init_state, make_chunk, make_step, optimizer, train  # noqa: F401
