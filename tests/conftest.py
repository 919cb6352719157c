"""Shared test fixtures: paths to the repo's scenes and to ../shared (skipped where absent)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# property tests draw the same examples on every run (a CI run on a fresh clone must not turn red by the
# luck of the draw); HYPOTHESIS_PROFILE=explore draws new ones (and keeps failures in .hypothesis/). No
# per-example deadline: Hypothesis' default (200 ms) fails an example by the machine's speed and load.
settings.register_profile("ci", derandomize=True, database=None, deadline=None)
settings.register_profile("explore", max_examples=5000, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

REPO = Path(__file__).resolve().parents[1]
SWEEPS = REPO / "sweeps"
SHARED = REPO.parent / "shared"

#: The slow tier (docs/contributing/testing.md): tests that take more than about 2 s each warm on a 2-core machine, or more
#: than about 4 s over their parameters: a real `python -m pounding_sweep` process or Dask cluster, a calibration,
#: a long reference integration, the notebook, a kernel compiled from scratch. Marked `slow` at collection, by
#: file and test function (every parametrisation); `python -m pytest -q -m "not slow"` runs the rest, the fast
#: tier for development; `python -m pytest -q` runs everything. Chosen from `--durations=0` of the whole suite
#: (each above 3 s, or above 6 s over its parameters, on this 2-core machine under a load of about 3), and the
#: tests that share a slow one's cached reference or fixture (they would pay for it alone); a new slow test goes
#: here. tests/test_tiers.py checks that every name here is a test.
SLOW = {
    "tests/cli/test_bad_inputs.py": ("test_bad_input_real_command",),
    "tests/cli/test_first_run.py": ("test_the_first_run_announces_its_compile_and_a_run_from_the_cache_says_nothing",),
    "tests/cli/test_signals.py": ("test_a_sweep_started_with_sigint_ignored_still_stops_at_ctrl_c",),
    "tests/engine/test_aside.py": (
        "test_both_scalar_kernels_load_the_scoring_code_the_second_process_compiled",
        "test_the_lane_kernel_loads_the_step_the_second_process_compiled",
    ),
    "tests/engine/test_lag_search.py": ("test_short_searches_stay_direct_and_long_ones_are_cheap",),
    "tests/engine/test_lanes.py": ("test_lane_kernel_metrics_equal_the_numpy_reference",),
    "tests/engine/test_nonlinear.py": (
        "test_law_kernel_converges_to_the_continuous_reference",
        "test_law_kernel_counts_and_flags_equal_the_discrete_reference",
        "test_law_kernel_histories_equal_the_discrete_reference",
        "test_single_impact_restitution_and_dashpot_work",
    ),
    "tests/engine/test_scalar.py": (
        "test_free_vibration_decays_as_the_modal_solution",
        "test_implicit_steps_whose_active_set_cycles_are_located_and_settle",
        "test_ivp_reference_is_converged_in_its_tolerance",
        "test_kernel_close_to_ivp_reference",
        "test_kernel_counts_equal_newmark_reference",
        "test_kernel_histories_equal_newmark_reference",
    ),
    "tests/risk/test_oracles.py": (
        "test_covariance_and_upcrossings_match_lyapunov_and_rice",
        "test_enveloped_covariance_matches_the_time_varying_lyapunov_equation",
        "test_probability_of_pounding_within_rice_bound_and_vanmarcke",
    ),
    "tests/risk/test_study.py": (
        "test_cli_runs_a_study",
        "test_dask_gives_the_same_study_bit_for_bit",
    ),
    "tests/scene/test_scene.py": ("test_cli_bad_input_exits_2_without_output",),
    "tests/scene/test_scene_properties.py": ("test_any_scene_loads_valid_or_raises_config_error",),
    "tests/sweep/test_best_table.py": (
        "test_a_changed_calibrate_is_never_left_stale_and_is_run_again",
        "test_a_kill_before_the_best_tables_rename_leaves_a_temporary_the_next_sweep_removes",
        "test_a_rerun_reuses_the_stored_calibration_and_a_new_one_says_what_it_does",
        "test_ctrl_c_before_the_calibration_is_one_line_and_leaves_the_grids_best_table",
        "test_two_result_folders_never_share_their_best_table",
    ),
    "tests/sweep/test_channel_offsets.py": ("test_a_real_sensor_delayed_is_found_by_its_clock",),
    "tests/sweep/test_calibrate.py": (
        "test_a_bound_that_excludes_the_truth_is_said",
        "test_a_contact_only_fit_of_the_same_data_is_pulled_off_and_says_so",
        "test_a_model_that_cannot_explain_the_data_is_said",
        "test_acceleration_channels_enter_the_calibration_filtered_like_the_kernel",
        "test_fitting_the_structure_recovers_contact_and_stiffness",
        "test_the_95_percent_intervals_cover_the_truth_over_50_noise_seeds",
        "test_the_shipped_calibration_scene_runs_end_to_end",
    ),
    "tests/sweep/test_frame_fits.py": (
        "test_a_frame_whose_stories_differ_is_recovered_story_by_story",
        "test_mode_ratios_made_by_the_reference_are_recovered",
    ),
    "tests/sweep/test_executors.py": (
        "test_a_worker_killed_mid_sweep_loses_and_duplicates_nothing",
        "test_cli_killed_with_sigkill_resumes_without_recomputing",
        "test_dataset_reads_in_pyarrow_and_duckdb_style_globs",
        "test_local_and_dask_give_identical_tables",
        "test_resume_with_a_changed_scene_is_refused",
    ),
    "tests/sweep/test_faults.py": (
        "test_a_lost_dask_node_completes_the_sweep_exactly_once",
        "test_a_lost_scheduler_is_one_line_and_the_sweep_resumes",
        "test_a_moved_project_folder_resumes_and_hashes_the_same",
        "test_a_second_sweep_on_a_folder_in_use_is_refused_at_once",
        "test_a_server_that_is_not_a_dask_scheduler_is_one_line",
        "test_ctrl_c_and_sigterm_under_a_local_cluster_are_one_line",
        "test_sigterm_on_the_local_executor_is_one_line",
    ),
    "tests/sweep/test_run.py": ("test_6hz_scene_writes_20_rows",),
    "tests/sweep/test_single_building.py": (  # the small walkthrough's calibration (one fixture, about 8 s) and figures
        "test_profiles_of_nothing_draw_no_figure",
        "test_the_small_walkthrough_calibrates_one_building",
        "test_the_walkthrough_figures_show_the_calibrated_run",
        "test_a_window_whose_optimum_is_on_a_bound_does_not_bound_the_model_error",  # a calibration of its own, 8 s
        "test_a_lower_residual_a_profile_finds_is_where_the_fit_goes_on",  # 30 s of the real Sine 1.5, twice fitted
    ),
    "tests/sweep/test_scoring.py": (
        "test_cli_summary_names_the_best_runs",
        "test_peak_memory_does_not_grow_with_runs",
        "test_plot_from_another_folder",
        "test_synthetic_experiment_hidden_parameters_are_the_best_cell",
    ),
    "tests/test_accuracy.py": (
        "test_accuracy_quick_ladder_6hz",
        "test_stability_quick_map_invariants",
    ),
    "tests/test_gaps.py": ("test_gaps_command_writes_the_study_and_refuses_bad_options",),
    "tests/test_notebook.py": ("test_notebook_runs_top_to_bottom",),
    "tests/test_plots.py": (
        "test_a_separated_scene_gets_no_empty_force_plot",
        "test_plot_command_writes_pngs",
    ),
    "tests/video/test_experiment_video.py": ("test_sweep_scored_from_a_video_finds_the_hidden_contact_parameters",),
    "tests/video/test_tracking.py": (
        "test_camera_roll_of_three_tenths_of_a_degree_is_removed",
        "test_touching_buildings_merge_without_identity_swap",
    ),
    "tests/video/test_video_chain.py": (
        "test_first_frequency_from_a_rendered_free_vibration_video_within_half_a_percent",
        "test_video_to_tracked_table_to_sweep_finds_the_hidden_contact_parameters",
    ),
    "tests/video/test_video_io.py": ("test_import_and_a_sweep_never_import_opencv",),
}


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: the slow tier (tests/conftest.py SLOW); -m 'not slow' leaves it out")


def pytest_collection_modifyitems(config, items):
    for item in items:
        try:
            path = Path(item.path).resolve().relative_to(REPO).as_posix()
        except ValueError:
            continue
        if getattr(item, "originalname", item.name) in SLOW.get(path, ()):
            item.add_marker(pytest.mark.slow)


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} not present: tests that read the paper's shared data need ../shared beside the repo")
    return SHARED


@pytest.fixture(autouse=True)
def _numpy_raises_on_fp_errors():
    """Tests make NumPy raise on invalid operations and division by zero (overflow too)."""
    with np.errstate(invalid="raise", divide="raise", over="raise"):
        yield
