"""Evaluation, Sec. IV-A.3: RMS, success, diversity, coverage and the reference baselines; the latency
measurement (:mod:`jgrounding.evaluation.latency`)."""
