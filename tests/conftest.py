import importlib.util
import os
from pathlib import Path

# jgrounding/io.py alone (importing the package would import jax before the environment below is set)
_spec = importlib.util.spec_from_file_location("_jg_io", Path(__file__).resolve().parents[1] / "jgrounding" / "io.py")
_io = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_io)

os.environ.setdefault("JAX_PLATFORMS", "cpu")
# One persistent compilation cache for the whole run, the machine's (jgrounding.io.cache_dir(), where grounding and
# the MJX engine keep theirs): both pytest-xdist workers and every subprocess a test starts (the CLI, training, the
# sharded and resumed runs) load what another already compiled instead of compiling it again.
# JGROUNDING_CACHE=off runs everything cold.
if _io.cache_dir() is not None:
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(_io.cache_dir()))
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.25")

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile("ci", deadline=None, max_examples=40, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ci")


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def own_model(tmp_path_factory):
    """``(library npz, checkpoint dir)`` of the docs' example model (tests/own_model.py), built once per session:
    tests/apps/test_own_model.py and the own_data.md page of tests/test_docs.py share it (read-only)."""
    from own_model import build

    return build(tmp_path_factory.mktemp("own_model"))


# --- `make test-fast` (pytest -m "not slow") -----------------------------------------------------------------
# Tests marked slow here rather than in their files: each took >= ~2.7 s (call + its share of a module fixture)
# in `pytest --durations=0` on 2 cores at load average 5-9 (docs/testing.md has the table and how to re-measure).
# `make test` and CI still run them. An entry names a test (``file::name``, a parametrized test as a whole) or a
# whole file (its module fixture is the slow part). An entry that matches nothing in a collected file is an
# error, so a renamed test cannot silently return to the fast set.
SLOW = {
    "tests/apps/test_cli_end_to_end.py::test_cli_jsonl_mode_and_direct_tuple": 8.1,
    "tests/apps/test_cli_end_to_end.py::test_cli_screen_and_current_flags": 5.7,
    "tests/apps/test_cli_end_to_end.py::test_interactive_loop_keeps_history": 2.8,
    "tests/apps/test_own_model.py::test_cli_text_with_own_checkpoint": 6.1,
    "tests/generators/test_few_step.py::test_networks_and_samples_have_the_flow_shapes": 10.1,
    "tests/generators/test_few_step.py::test_training_lowers_the_loss_on_a_tiny_problem": 9.6,
    "tests/generators/test_few_step.py::test_one_step_through_jg_sample_passes_the_gate_and_traces_once": 3.3,
    "tests/generators/test_few_step.py::"
    "test_the_exact_field_of_a_point_mass_has_zero_loss_and_a_wrong_one_does_not": 4.0,
    "tests/generators/test_generator_options.py::test_guidance_extrapolates_from_the_null_condition": 3.6,
    "tests/generators/test_generators.py::test_resumed_training_equals_uninterrupted": 8.1,
    "tests/generators/test_generators.py::test_cnn_regressor_collapses_to_the_mean": 4.9,
    "tests/generators/test_generators.py::test_distributional_generators_recover_both_modes": 6.8,
    "tests/policy/test_sampling.py::test_samples_do_not_depend_on_the_batch_bucket_or_chunking": 2.7,
    "tests/evaluation/test_distribution.py::test_reference_brackets_hold": 31.7,  # the refs fixture (k=8)
    "tests/evaluation/test_distribution.py::test_perfect_replay_ranks_above_hedge_and_collapse": 0.1,
    "tests/evaluation/test_distribution.py::test_prec_at_tau_alone_cannot_tell_a_hedge_from_a_replay": 0.1,
    "tests/evaluation/test_latency.py::test_raw_conditioning_is_timed_through_the_core_and_says_so": 3.0,
    "tests/library/test_library_metrics.py::test_another_seed_gives_another_library": 22.9,
    "tests/library/test_library_metrics.py::test_regeneration_is_byte_identical": 38.9,
    "tests/library/test_own_library.py::test_three_tendons_train_and_generate": 23.3,
    "tests/library/test_own_library.py::test_train_cli_and_sample_three_tendons": 4.6,
    "tests/library/test_signatures.py": 20.7,  # simulates the whole library once
    "tests/serving/test_load_faults.py": 26.5,  # live streams of several seconds each
    "tests/serving/test_page.py": 6.5,  # headless Chromium
    "tests/sim/test_render_views.py": 5.3,  # OSMesa renders
    "tests/sim/test_trunk.py::test_contact_pruning_is_exact": 3.0,
    "tests/study/test_study_browser.py": 46.0,  # headless Chromium, the model through the live stream
    "tests/study/test_study_resume.py": 18.0,  # servers killed with SIGKILL and restarted
    "tests/study/test_study_server.py::test_a_participant_goes_through_and_the_executed_commands_are_recorded": 11.2,
    "tests/test_config.py::test_a_checkpoint_without_sizes_loads_with_table_one_sizes_or_is_refused": 2.7,
    "tests/test_config.py::test_checkpoint_records_model_sizes_and_restores_them": 5.1,
    "tests/test_config.py::test_model_sizes_reach_the_network": 4.0,
    "tests/test_docs.py::test_python_blocks_run[README.md]": 5.3,
    "tests/test_docs.py::test_python_blocks_run[docs/distributed.md]": 4.5,
    "tests/test_docs.py::test_python_blocks_run[docs/own_data.md]": 4.9,
    "tests/test_docs.py::test_python_blocks_run[docs/serving.md]": 6.2,
    "tests/test_fuzz.py::test_cli_fuzzed_arguments_succeed_or_exit_2_with_usage": 8.4,
    "tests/test_fuzz.py::test_non_finite_conditions_are_never_emitted": 3.0,
    "tests/test_fuzz.py::test_sample_with_valid_fuzzed_arguments_is_safe": 8.4,
    "tests/training/test_distributed.py::test_four_forced_host_devices_form_one_data_mesh": 20.7,  # sharded_run
    "tests/training/test_distributed.py::test_training_chunk_keeps_the_seed_axis_split": 0.0,
    "tests/training/test_distributed.py::test_sharded_training_equals_single_device": 0.0,
    "tests/training/test_distributed.py::test_sharded_generation_equals_single_device": 0.0,
    "tests/training/test_retrace.py::test_sampler_traces_once_across_calls": 4.0,
}


def _slow_entry(nodeid: str) -> str | None:
    for entry in (nodeid, nodeid.split("[")[0], nodeid.split("::")[0]):
        if entry in SLOW:
            return entry
    return None


@pytest.hookimpl(tryfirst=True)  # before -m "not slow" deselects
def pytest_collection_modifyitems(config, items):
    used, files = set(), {item.nodeid.split("::")[0] for item in items}
    for item in items:
        entry = _slow_entry(item.nodeid)
        if entry is not None:
            used.add(entry)
            item.add_marker(pytest.mark.slow)
    stale = sorted(e for e in SLOW if e.split("::")[0] in files and e not in used)
    partial = config.option.keyword or config.option.deselect or any("::" in str(a) for a in config.args)
    if stale and not partial:  # a -k, --deselect or file::test selection may leave entries out
        raise pytest.UsageError(f"tests/conftest.py SLOW names tests that do not exist (renamed?): {stale}")
    missing = sorted(f for f in FILE_SECONDS if not (config.rootpath / f).is_file())
    if missing:
        raise pytest.UsageError(f"tests/conftest.py FILE_SECONDS names files that do not exist (moved?): {missing}")
    items[:] = longest_files_first(items)


# --- the order files start in (`make test`: pytest-xdist, -n auto --dist loadfile --no-loadscope-reorder) ------
# Each worker takes a whole file at a time, in collection order. Starting the longest files first (LPT
# scheduling) keeps one long file from starting last and running alone at the end. Seconds per file (calls +
# fixtures) in `pytest -n 2 --dist loadfile --durations=0` on 2 cores; test_trunk.py's MJX compiles are cold, as
# on a machine's first run (65 s alone since the flat-scan rollout; warm: 33 s). Only the order depends on these: a
# stale figure costs time, never a test.
FILE_SECONDS = {
    "tests/sim/test_trunk.py": 75.0,
    "tests/apps/test_cli_end_to_end.py": 104.5,
    "tests/library/test_library_metrics.py": 61.5,
    "tests/study/test_study_browser.py": 50.6,
    "tests/serving/test_load_faults.py": 29.6,
    "tests/training/test_distributed.py": 29.4,
    "tests/training/test_resume.py": 22.9,
    "tests/study/test_study_resume.py": 20.6,
    "tests/policy/test_sampling.py": 19.3,
    "tests/test_device_check.py": 17.6,
    "tests/library/test_own_library.py": 15.9,
    "tests/test_docs.py": 13.4,
    "tests/study/test_study_server.py": 12.3,
    "tests/generators/test_few_step.py": 11.5,
    "tests/evaluation/test_distribution.py": 11.3,
    "tests/test_fuzz.py": 10.6,
}


def longest_files_first(items: list) -> list:
    """``items`` with the files of ``FILE_SECONDS`` first, longest first; within a file and among the rest the
    collection order is kept (``sorted`` is stable)."""
    return sorted(items, key=lambda item: -FILE_SECONDS.get(item.nodeid.split("::")[0], 0.0))
