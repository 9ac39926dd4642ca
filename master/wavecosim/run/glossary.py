"""What a run's files hold: the meaning and unit of every column of trajectory.csv and every key of
summary.json and metadata.json (the columns of steps.csv are described where they are made: the
runner's STEP_DESCRIBED and each observer's `described`). docs/outputs.md is generated from here
(scripts/docs_tables.py), and a test runs the scenes and fails on a column or key not described.

Units: "1" a pure number, "text" a label, "" no one unit; energies in J and waves in sqrt(J) where
the ports carry SI units (in general: the unit of the FMUs' stored energy H, and its square root).
"""

TRAJECTORY = {
    "time": ("the grid time t₀ + n·Δt, written as the shortest decimal that reads back to the same number", "s"),
    "<column>": ("an output, or an input a signal drives, of one subsystem, named SUBSYSTEM.variable unless "
                 "`outputs:` names it: its value at the grid time (an input: the value it held over the step "
                 "ending there)", "the variable's unit in its FMU's modelDescription"),
}

SUMMARY = {
    # the run (runner.py)
    "label": ("the run's label: the master and its budget (`dr_K8`), `monolithic` for the reference", "text"),
    "scenario": ("the scenario's name", "text"),
    "master": ("the master that ran", "text"),
    "K": ("the inner budget", "1"),
    "eps": ("the inner tolerance, or null", "sqrt(J)"),
    "dt": ("the macro-step", "s"),
    "T": ("the stop time", "s"),
    "start_time": ("the start time t₀", "s"),
    "times_from": ("where `dt`, `start_time` and `T` came from, each in words: the command line, the scenario "
                   "file, the SSD's DefaultExperiment, its OSP annotation (`osp:FixedStepAlgorithm`), OSP-IS "
                   "(`OspSystemStructure.xml`), OMSimulator's fixed-step master, or an FMU's DefaultExperiment",
                   "text"),
    "steps": ("macro-steps made", "1"),
    "status": ("`finished`, `failed`, `interrupted`, or `suspect`: the run went to its end but an observer "
               "doubts it (the freeze watch found an FMU that does not advance; `message` says which)", "text"),
    "message": ("why the run failed or ended early (an FMU that asked to end it); empty otherwise", "text"),
    "iterations_mean": ("inner iterations per macro-step, on average", "1"),
    "iterations_max": ("the most inner iterations in one macro-step", "1"),
    "wall_time_s": ("the master's own time: its calls (a step, or a block of steps on the C kernel route with "
                    "the certificates computed inside it), not the other observers or the files", "s"),
    "total_time_s": ("from the FMUs opened to the summary: steps, observers, rows written", "s"),
    "loop_time_s": ("from the first macro-step to the last row written: the run's cost beyond set-up", "s"),
    "real_time_factor": ("simulated time over the master's wall time", "1"),
    "fmu_calls": ("FMU calls the run made from its first step on, over every FMU (those stepped alone, signals only, "
                  "too): `doStep`, `save` and `restore` (state get and set), `get` and `set` (value transfers: "
                  "fmi2Get/Set Real, Integer, Boolean, String and their FMI 3 kin, one per call whatever its length), "
                  "each counted where the call is made; the same on the C kernel route and the Python one, but for "
                  "`get` with `energy_guard: monolithic` (its check reads H apart after a step made alone, where the "
                  "kernel's blocks use the run's own reading); the observers' own calls (certificates, probes) not "
                  "counted", "1"),
    "fmu_calls_by_subsystem": ("the same per subsystem (they add up to `fmu_calls`)", "1"),
    "fmu_tolerance": ("per subsystem whose FMU is set up with a tolerance, the one it was set up with (its "
                      "`tolerance`, else its DefaultExperiment's, at most master.fmu_tolerance)", "1"),
    "output_interval": ("a row is written every this many macro-steps (and at the last)", "steps"),
    "energy_guard": ("the energy guard in force: `ledger`, `monolithic`, `off`, or `n/a` for a master that does "
                     "not roll back", "text"),
    "block_steps": ("macro-steps made in blocks of many steps per call of the C kernel", "1"),
    "quirks": ("per subsystem, the doStep flag it ran with, `no_set_fmu_state_prior`, and `chosen_by` (probe, "
               "quirks key, no rollback, default); what the probes found is in metadata.json", "–"),
    "notes": ("the set-up's warnings (quirks found, port signs probed), each also printed once on stderr", "text"),
    # the freeze watch (observers/freeze_watch.py)
    "freeze_watch": ("`steps`: how many macro-steps with changing inputs and the same outputs make a subsystem "
                     "suspect; `suspect`: per such subsystem, `from_step`, `from_t` and `steps` of its longest "
                     "frozen stretch (docs/troubleshooting.md)", "1; s"),
    # the energy guard (masters/ledger.py, masters/energy_guard.py)
    "energy_guard_steps": ("macro-steps the energy guard redid", "1"),
    "energy_guard_extra_doSteps": ("doStep calls the redos cost", "1"),
    "max_ledger": ("the largest ledger value Lⁿ over the run (at or below roundoff: the interface never supplied "
                   "net energy)", "J"),
    "ledger_final": ("the ledger at the end, L_N", "J"),
    "ledger_tolerance": ("the roundoff the ledger allows: 10⁻¹² (plus a wave adapter's map noise) times the "
                         "energy that went through the interface", "J"),
    "energy_guard_actions": ("steps per ledger action: `kept` and each redo stage (`iterated`, `projected`, "
                             "`blended`, `anchored`, `scaled`, `zero`)", "1"),
    "step_time_us": ("under `master.deadline_us`: the time of a step and its guard, `median`, `p99`, `max` (by "
                     "nearest rank) and `count`", "µs"),
    "guarded_step_time_us": ("the same over the steps the ledger redid (empty when none)", "µs"),
    "deadline_bound": ("under `master.deadline_us`: the bound a step keeps, `bound_us` = `deadline_us` + "
                       "`round_us` (one evaluation round of every subsystem), the shares of steps within it "
                       "(`within`, `guarded_within`, and `on_cpu_within` among the `on_cpu_steps` the machine "
                       "did not preempt) and what `step_time` measures", "µs; shares 1"),
    # gamma (observers/gamma.py, core/gamma.py)
    "gamma_mode": ("`fixed`, or the mode that chose γ: `auto`, `auto-retune`, `fastest`, `fast-unsafe`", "text"),
    "gamma_initial": ("γ per subsystem at the first step", "effort/flow of each port"),
    "gamma_final": ("γ per subsystem at the end", "effort/flow of each port"),
    "gamma_min": ("the smallest γ per subsystem over the run (auto-retune lowers it)", "effort/flow of each port"),
    "gamma_changes": ("how often auto-retune changed γ", "1"),
    "gamma_fne_bounds": ("per subsystem, the largest γ at which its frozen map is firmly nonexpansive (Condition "
                         "1), λ_min of its incremental port impedance", "effort/flow of each port"),
    "gamma_probe": ("per subsystem, the probe γ was chosen from: its finite-difference `step`, the `check_step` "
                    "ten times larger, their `jacobian_difference`, whether they `agreed`, `steps_tried`",
                    "the port's input units"),
    "gamma_rate_estimate": ("the inner iteration's predicted contraction per iteration at the chosen γ", "1"),
    "gamma_guaranteed": ("whether every γ chosen kept Condition 1 (false only with fast-unsafe)", "boolean"),
    # the Condition 1 watch (observers/fne_watch.py)
    "fne_watch_ok": ("whether the watch's margin stayed ≥ 0 (within 10⁻⁶) all run", "boolean"),
    "fne_watch_first_failure": ("the first failure, {`step`, `t`, `subsystem`, `margin`, `gamma`}, or null", "–"),
    "fne_watch_failed_steps": ("macro-steps at which a margin estimate failed", "1"),
    "fne_watch_min_margin": ("per subsystem, the smallest margin the watch estimated", "1"),
    "fne_watch_probed_steps": ("macro-steps at which the watch probed the frozen maps (K < 2)", "1"),
    # the sampled certificates (observers/certificates.py)
    "max_augmented_pos": ("the largest positive part of Theorem 1's augmented residual at the sampled steps "
                          "(0: the theorem held)", "J"),
    "min_fne_margin": ("the smallest sampled FNE margin over every subsystem (≥ 0: Condition 1 held)", "1"),
    "min_fne_margin_by_subsystem": ("the same per subsystem", "1"),
    "certificates_every": ("the certificates were computed at the steps n with n % every == 0", "steps"),
    "certificates_every_chosen": ("how `every` was chosen", "text"),
    # Condition 2 and the stored energy (observers/passivity.py)
    "max_passivity_pos": ("the largest positive Condition 2 residual rᵢ over the run (roundoff for passive "
                          "FMUs without sources)", "J"),
    "max_passivity_pos_by_subsystem": ("the same per subsystem", "J"),
    "H_initial": ("the stored energy Σᵢ Hᵢ at the start", "J"),
    "H_final": ("the stored energy at the end", "J"),
    "H_growth": ("the largest stored energy over the run divided by H_initial (≤ 1 in a scene without "
                 "sources: no energy came through the interface)", "1"),
    "port_energy_by_subsystem": ("per subsystem without H, the energy into its port over the run", "J"),
    "max_interface_injection": ("the most energy the interface supplied in one macro-step (its positive part)",
                                "J"),
    "energy_drift": ("the energy the interface supplied over the run, Σₙ interface_supply", "J"),
    "certificates_unavailable": ("the figures this run could not compute, and why (an FMU without H)", "text"),
    # errors against the monolithic reference (observers/errors.py)
    "max_error": ("the largest `error` over the grid; without `error` columns, the largest of `errors`",
                  "the error columns' units; 1 without them"),
    "rms_error": ("the root mean square of `error` over the grid; without `error` columns, the largest "
                  "column's root mean square |Δy| over the grid divided by its scale", "the error columns' units; 1 without them"),
    "final_error": ("`error` at the last grid point; without `error` columns, the largest column's |Δy| "
                    "there divided by its scale", "the error columns' units; 1 without them"),
    "errors": ("per recorded Real output, the largest |Δy| against the monolithic reference over the grid "
               "divided by the column's range in the reference (max − min); a column constant to 10⁻⁹ of its "
               "size by its largest |value|, one zero throughout by 1", "1"),
    # the tolerance mode (masters/adaptive.py, observers/step_control.py) and the fine reference (run/fine.py)
    "tolerance": ("the tolerance mode's relative tolerance", "1"),
    "estimate": ("the tolerance mode's error estimate as run (`predictor`, `coupling`, `doubling`, or which "
                 "subsystems take `coupling`)", "text"),
    "pilot": ("whether the tolerance mode made its pilot steps first (every watched value zero at the start: "
              "their sizes from 20 steps across the span, then everything put back)", "boolean"),
    "accepted_steps": ("macro-steps accepted by the step control (the rows after t₀)", "1"),
    "steps_over_tolerance": ("accepted steps whose error estimate was above their allowance: kept because no "
                             "FMU could be put back, or made at dt_min (the first is warned of)", "1"),
    "rejected_steps": ("macro-steps rejected and redone smaller", "1"),
    "dt_smallest": ("the smallest accepted macro-step", "s"),
    "dt_largest": ("the largest accepted macro-step", "s"),
    "true_error": ("with `--reference fine`: the largest over the error columns of max over time |x − x_ref| / "
                   "range(x_ref), x_ref the monolithic reference at a refined step interpolated onto the run's times",
                   "1"),
    "true_error_by_column": ("the same per column", "1"),
    "true_reference_dt": ("the refined step the reference of `true_error` ran at", "s"),
    "true_reference_richardson": ("whether the reference of `true_error` is Richardson's extrapolation "
                                  "2 x_(h/2) − x_h of runs at the refined step h and at half of it (where the "
                                  "monolithic step's error is first order in h: `error_order` 1)", "boolean"),
    # the master (masters/)
    "error_order": ("the order in the macro-step of the master's error over the run: 2 for an iterating wave "
                    "master over FMUs' own wave ports that no signal drives, else 1 (an input is held over "
                    "the step)", "1"),
    "fast_path": ("whether the master ran on the C kernel route", "boolean"),
    "fast_note": ("why it ran on the route it did", "text"),
    "threads": ("threads that evaluated the subsystems", "1"),
    "thread_note": ("why that many", "text"),
    "options": ("DR: `manual`, or `auto` (γ, λ and the Anderson window chosen from the scene)", "text"),
    "relaxation": ("DR: the relaxation λ used", "1"),
    "relaxation_rates": ("DR with `relaxation: auto`: the predicted contraction without (`rate_plain`) and with "
                         "(`rate_relaxed`) the λ chosen", "1"),
    "anderson": ("DR: the Anderson window", "1"),
    "anderson_memory": ("DR: whether the Anderson differences are kept across steps", "boolean"),
    "anderson_extrapolate": ("DR: whether b* is the Anderson combination of the responses", "boolean"),
    "start": ("DR: the start of the inner loop as run (`paper`, `extrapolated`, `previous`)", "text"),
    # ports and signals (core/scene.py)
    "port_signs": ("per physical port, `sign` per channel (power into the FMU = sign·e·f), whether it was "
                   "`probed`, and the `probe` (`step`, `slope`, `check_step`, `check_slope`, `steps_tried`)",
                   "1"),
    "wave_adapter": ("per subsystem reached through the wave adapter: `map_evaluations`, `doSteps`, "
                     "`doSteps_per_evaluation`, `stalled_queries` and `worst_stalled_residual` (relative)", "1"),
    "signals": ("signal connections in the scenario", "1"),
    "signal_driven_subsystems": ("subsystems with a port whose inputs signals drive", "text"),
    "signal_note": ("why their energy growth is not a passivity violation", "text"),
}

METADATA = {
    "scenario": ("the scenario as resolved: every key of the scenario file after defaults, the FMUs' "
                 "DefaultExperiment and the command line's options; each time table (`sources`) by its `csv` file, "
                 "`sha256`, `rows` and `columns`, its values left in the file", "–"),
    "units": ("the unit of every column: `trajectory` (from the FMUs' modelDescriptions: a variable's unit, "
              "else its declared type's; \"\" where none is given) and `steps` (as this page gives them, "
              "γ and the error resolved from the FMUs)", "–"),
    "gammas": ("γ per subsystem at the end of the run", "effort/flow of each port"),
    "quirks": ("per subsystem, what the quirk probes at set-up found for its FMU file (`found`) and what it ran "
               "with: `no_set_fmu_state_prior` (the doStep flag), `chosen_by` (probe, quirks key, no rollback, "
               "default), `own_copy` (its own copy of the binary); docs/troubleshooting.md", "–"),
    "versions": ("the versions of wavecosim, Python, numpy, scipy and fmpy", "text"),
    "fmus": ("per subsystem, its FMU's `path`, `sha256`, `fmiVersion` and `guid`", "text"),
    "host": ("the machine: `node`, `machine`, `system`, `cpus`", "text"),
    "written": ("when the file was written (UTC, ISO 8601)", "text"),
}
