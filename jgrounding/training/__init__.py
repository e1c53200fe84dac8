"""Training: the compiled loop (AdamW, scan chunks, vmap over seeds), checkpoints and device meshes."""

from jgrounding.training.loop import (  # noqa: F401
    TrainConfig,
    TrainState,
    eval_params,
    init_state,
    make_chunk,
    make_step,
    optimizer,
    train,
)
