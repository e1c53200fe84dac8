"""The policy: the public sampler ``jg.sample`` over the shipped checkpoints (:mod:`jgrounding.policy.sampling`).

Its own layer, above training (it restores checkpoints) and below evaluation, the apps and the experiments
(which call it as users do), as openpi's ``policies`` sit above its models and training.
"""
