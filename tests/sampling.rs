//! Sampled simulation (docs/sampling.md): every unit sampled is the exact simulation, the
//! estimate does not depend on the thread count, the interval narrows with the rate, the image
//! stays exact, and bad rates are refused.

use std::process::Command;

use vizsim::arch::sampling::Sampling;
use vizsim::arch::sdram_module::SdramMemory;
use vizsim::arch::voxel_memory::VoxelMemory;
use vizsim::config::HardwareConfig;
use vizsim::experiment::spec::run_key;
use vizsim::run::{self, Model, Probes, RunDescription, RunReport};

/// A sampling at `rate` with units of 16 rays, so that a test-sized frame has the
/// `MIN_SAMPLED_UNITS` units a frame needs to be sampled at all.
fn small_units(rate: f64) -> Sampling {
    Sampling {
        unit_rays: 16,
        ..Sampling::new(rate, "test").unwrap()
    }
}

/// A leaping frame of the metaballs phantom: 96×96 rays, 576 units of 16.
fn description(sample: Option<f64>) -> RunDescription {
    let mut hardware = HardwareConfig::default_config();
    hardware.occupancy.subcube = 4;
    RunDescription {
        view: "orbit:5/72".into(),
        size: (96, 96),
        sample: sample.map(small_units),
        ..RunDescription::new("phantom:metaballs:48", "class", Model::Cycle, hardware)
    }
}

fn simulate(sample: Option<f64>) -> RunReport {
    run::run(&description(sample), None, Probes::default()).unwrap()
}

#[test]
fn sampling_every_unit_gives_the_exact_cycles_and_image() {
    // The metaballs frame, and a frame whose rays also issue leaps after ERT before its
    // feedback arrives (counted by the pipeline, not by the functional model: an estimate
    // scaled by the functional steps was 36 cycles off there at rate 1).
    let shells = || {
        let mut hardware = HardwareConfig::default_config();
        hardware.occupancy.subcube = 2;
        RunDescription {
            view: "orbit:5/72".into(),
            size: (64, 64),
            ..RunDescription::new("phantom:shells:48", "class", Model::Cycle, hardware)
        }
    };
    let with_rate = |run: RunDescription, rate: Option<f64>| RunDescription {
        sample: rate.map(|rate| Sampling::new(rate, "test").unwrap()),
        ..run
    };
    for frame in [description(None), shells()] {
        let exact = run::run(&frame, None, Probes::default()).unwrap();
        let sampled = run::run(
            &with_rate(frame.clone(), Some(1.0)),
            None,
            Probes::default(),
        )
        .unwrap();
        assert!(
            exact.measurements.discarded_after_ert.unwrap() > 0,
            "ERT acts"
        );
        assert_eq!(sampled.measurements.cycles, exact.measurements.cycles);
        assert_eq!(sampled.measurements.cycles_ci95, Some(0.0));
        assert_eq!(sampled.measurements.sampled, Some(true));
        assert_eq!(
            sampled.measurements.stall_cycles,
            exact.measurements.stall_cycles
        );
        assert_eq!(
            sampled.measurements.discarded_after_ert,
            exact.measurements.discarded_after_ert
        );
        assert_eq!(sampled.measurements.row_hits, exact.measurements.row_hits);
        assert_eq!(
            sampled.measurements.row_misses,
            exact.measurements.row_misses
        );
        assert_eq!(sampled.frame.pixels, exact.frame.pixels);
        // Exact runs carry no sampling fields.
        assert_eq!(exact.measurements.cycles_ci95, None);
        assert_eq!(exact.measurements.sampled, None);
    }
}

#[test]
fn a_sampled_run_has_the_exact_image_and_counts_and_a_plausible_estimate() {
    let exact = simulate(None);
    let sampled = simulate(Some(0.2));
    let estimate = sampled.sampling.as_ref().expect("sampled report");
    assert!(estimate.measured_units < estimate.units, "{estimate:?}");
    assert_eq!(sampled.frame.pixels, exact.frame.pixels);
    // The counts are the functional model's (exact), not estimates.
    let functional = run::run(
        &RunDescription {
            model: Model::Step,
            sample: None,
            ..description(None)
        },
        None,
        Probes::default(),
    )
    .unwrap();
    assert_eq!(sampled.measurements.steps, functional.measurements.steps);
    assert_eq!(
        sampled.measurements.samples,
        functional.measurements.samples
    );
    let (estimated, true_cycles) = (
        sampled.measurements.cycles.unwrap() as f64,
        exact.measurements.cycles.unwrap() as f64,
    );
    // Not a coverage claim (docs/sampling.md has those): the estimate is in the right range.
    assert!(
        (estimated - true_cycles).abs() < 0.1 * true_cycles,
        "{estimated} vs {true_cycles}"
    );
}

#[test]
fn the_estimate_does_not_depend_on_the_thread_count() {
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| simulate(Some(0.15)))
            .measurements
    };
    assert_eq!(on(1), on(3));
}

#[test]
fn the_interval_narrows_as_the_rate_grows() {
    let ci = |rate: f64| simulate(Some(rate)).measurements.cycles_ci95.unwrap();
    let (low, middle, all) = (ci(0.1), ci(0.5), ci(1.0));
    assert!(low > middle && middle > all, "{low} {middle} {all}");
    assert_eq!(all, 0.0);
}

#[test]
fn sampled_and_exact_runs_never_share_a_key() {
    let exact = description(None);
    let sampled = description(Some(0.05));
    assert_ne!(run_key(&exact), run_key(&sampled));
    assert_ne!(run_key(&sampled), run_key(&description(Some(0.1))));
    // The exact description serialises as before the field existed.
    let json = serde_json::to_value(&exact).unwrap();
    assert!(json.get("sample").is_none());
}

#[test]
fn the_step_model_refuses_sampling() {
    let run = RunDescription {
        model: Model::Step,
        ..description(Some(0.1))
    };
    let Err(error) = run::run(&run, None, Probes::default()) else {
        panic!("a sampled step-model run was accepted");
    };
    assert!(error.to_string().contains("cycle model"), "{error}");
}

#[test]
fn bad_sample_rates_are_refused_naming_the_flag() {
    for rate in ["0", "-0.1", "1.5", "NaN", "inf", "abc", ""] {
        let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
            .args([
                "sim",
                "--dataset",
                "phantom:sphere:16",
                "--size",
                "16x16",
                "--sample",
                rate,
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "--sample {rate} accepted");
        assert!(stderr.contains("--sample"), "--sample {rate}: {stderr}");
        assert!(!stderr.contains("panicked"), "--sample {rate}: {stderr}");
    }
}

#[test]
fn an_experiment_with_a_bad_rate_is_refused_naming_the_field() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-sampling-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.toml");
    std::fs::write(
        &file,
        "name = \"bad\"\ndatasets = [\"phantom:sphere:16\"]\nmodes = [\"none\"]\n\
         models = [\"cycle\"]\nsample = 1.5\n[frames]\norbit = 1\nsize = \"16x16\"\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["sweep", file.to_str().unwrap(), "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("sample"), "{stderr}");
    assert!(!dir.join("out").join("results.jsonl").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sampled run simulates a share of its rays in detail: all of them at rate 1; at rate 0.05
/// on a 256×256 frame (512 units of 128 rays) the 26 sampled units with their 16-ray warm-ups
/// (about 0.05 × 1.125) plus the first and last unit: about 0.06.
#[test]
fn the_simulated_share_follows_the_rate() {
    let rays = 256 * 256;
    let share = |rate: f64| Sampling::new(rate, "test").unwrap().simulated_share(rays);
    assert_eq!(share(1.0), 1.0);
    let at_5_percent = share(0.05);
    assert!((0.055..0.07).contains(&at_5_percent), "{at_5_percent}");
    assert!(share(0.01) < at_5_percent && at_5_percent < share(0.2));
}

/// The dry run's time estimate knows about sampling: the same sweep sampled at 0.05 is
/// estimated at about a fifth of its exact cost (the functional frame plus the simulated
/// share; measured on the protocol: 1,233 CPU-seconds against about 8,400).
#[test]
fn a_dry_run_estimates_a_sampled_sweep_below_the_exact_one() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-sampling-dry-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let estimate = |sample: &str| -> f64 {
        let file = dir.join(format!("experiment{}.toml", sample.len()));
        std::fs::write(
            &file,
            format!(
                "name = \"dry\"\ndatasets = [\"phantom:metaballs:64\"]\ntf = [\"class\"]\n\
                 modes = [\"none\"]\nmodels = [\"cycle\"]\n{sample}\n\
                 [frames]\norbit = 72\nsize = \"256x256\"\n"
            ),
        )
        .unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
            .args(["sweep", file.to_str().unwrap(), "--dry-run", "--out"])
            .arg(dir.join("out"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(out.status.success(), "{text}");
        // "... estimate under 1 s + 26 s on 2 threads ...": the cycle model's part.
        let part = text
            .split(" + ")
            .nth(1)
            .expect("the cycle model's estimate");
        let mut words = part.split_whitespace();
        let value: f64 = words.next().unwrap().parse().unwrap();
        value
            * match words.next().unwrap() {
                "s" => 1.0,
                "min" => 60.0,
                "h" => 3600.0,
                unit => panic!("unit {unit} in {text}"),
            }
    };
    let exact = estimate("");
    let sampled = estimate("sample = 0.05");
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        (0.12 * exact..0.3 * exact).contains(&sampled),
        "sampled {sampled} s, exact {exact} s"
    );
}

/// Functional warming of the refresh phase (docs/sampling.md, "Warming"): a segment inside the
/// frame meets its first refresh `refresh_interval - phase % refresh_interval` cycles in, a
/// cold memory (the frame's start) after a whole interval.
#[test]
fn a_warmed_memory_refreshes_at_its_phase() {
    let config = HardwareConfig::default_config();
    let interval = config.sdram.refresh_interval as u64;
    let first_refresh = |phase: Option<u64>| {
        let mut memory = SdramMemory::new(&config.memory, &config.sdram, [64, 64, 64], 100.0);
        if let Some(phase) = phase {
            memory.warm_refresh_phase(phase);
        }
        let mut completed = Vec::new();
        (0..3 * interval)
            .find(|&now| {
                memory.step(now, &mut completed);
                memory.stats_json()["refreshes"].as_u64() == Some(4)
            })
            .expect("every module refreshes within three intervals")
    };
    assert_eq!(first_refresh(None), interval);
    assert_eq!(first_refresh(Some(1000)), interval - 1000);
    assert_eq!(first_refresh(Some(interval + 7)), interval - 7);
}

/// A frame of fewer than `MIN_SAMPLED_UNITS` units is simulated whole: at 64×64 (32 units of
/// 128 rays) rate 0.05 used to draw 2 strata, and two all-background units that agreed gave an
/// estimate 4.8× the true cycles with a ±2 % interval. A distance volume samples with the long
/// warm-up.
#[test]
fn a_small_frame_is_simulated_whole_and_a_distance_volume_warms_longer() {
    let mut hardware = HardwareConfig::default_config();
    hardware.bricks.size = 16;
    let frame = RunDescription {
        view: "orbit:4/8".into(),
        size: (64, 64),
        ..RunDescription::new("phantom:metaballs:48", "class", Model::Cycle, hardware)
    };
    let exact = run::run(&frame, None, Probes::default()).unwrap();
    let sampled = run::run(
        &RunDescription {
            sample: Some(Sampling::new(0.05, "test").unwrap()),
            ..frame.clone()
        },
        None,
        Probes::default(),
    )
    .unwrap();
    let estimate = sampled.sampling.as_ref().unwrap();
    assert_eq!(estimate.units, 32);
    assert_eq!(estimate.measured_units, estimate.units);
    assert_eq!(sampled.measurements.cycles, exact.measurements.cycles);
    assert_eq!(sampled.measurements.cycles_ci95, Some(0.0));
    assert_eq!(
        estimate.warmup_rays,
        vizsim::arch::sampling::DEFAULT_WARMUP_RAYS
    );

    let mut distance = description(Some(0.2));
    distance.hardware.occupancy.structure = vizsim::config::LeapStructure::Distance;
    distance.hardware.occupancy.subcube = 0;
    let report = run::run(&distance, None, Probes::default()).unwrap();
    let estimate = report.sampling.as_ref().unwrap();
    assert_eq!(
        estimate.warmup_rays,
        vizsim::arch::sampling::LONG_WARMUP_RAYS
    );
    assert!(estimate.measured_units < estimate.units);
}
