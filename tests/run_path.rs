//! One run path: `render --model fixed`, `sim` and a one-run sweep of the same description give
//! the same steps, cycles and image, because all of them call `vizsim::run::execute`.

use std::path::PathBuf;
use std::process::{Command, Output};

fn vizsim(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run vizsim");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-runpath-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn pixels(path: &std::path::Path) -> Vec<u8> {
    image::open(path).unwrap().to_rgba8().into_raw()
}

#[test]
fn render_sim_and_a_one_run_sweep_agree() {
    let dir = scratch("agree");
    let frame = [
        "--dataset",
        "phantom:metaballs:32",
        "--tf",
        "class",
        "--view",
        "orbit:5/72",
        "--size",
        "24x20",
        "--subcube",
        "4",
    ];
    let (fixed_png, fixed_json) = (dir.join("fixed.png"), dir.join("fixed.json"));
    let mut args = vec!["render", "--model", "fixed"];
    args.extend(frame);
    args.extend(["-o", fixed_png.to_str().unwrap()]);
    args.extend(["--json", fixed_json.to_str().unwrap()]);
    vizsim(&args);
    let (sim_png, sim_json) = (dir.join("sim.png"), dir.join("sim.json"));
    let mut args = vec!["sim"];
    args.extend(frame);
    args.extend(["-o", sim_png.to_str().unwrap()]);
    args.extend(["--json", sim_json.to_str().unwrap()]);
    vizsim(&args);

    let experiment = dir.join("one.toml");
    std::fs::write(
        &experiment,
        r#"name = "one"
datasets = ["phantom:metaballs:32"]
tf = ["class"]
modes = ["ert+leap4"]
models = ["step", "cycle"]
[frames]
orbit = 72
select = [5]
size = "24x20"
"#,
    )
    .unwrap();
    let out = dir.join("sweep");
    vizsim(&[
        "sweep",
        experiment.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(out.join("results.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let of = |model: &str| {
        lines
            .iter()
            .find(|l| l["model"] == model)
            .unwrap_or_else(|| panic!("no {model} line"))
    };

    let (fixed, sim) = (json(&fixed_json), json(&sim_json));
    assert!(fixed["steps"].as_u64().unwrap() > 0);
    assert!(fixed["leaps"].as_u64().unwrap() > 0, "the view must leap");
    for field in ["steps", "samples", "leaps", "rays_terminated_early"] {
        assert_eq!(fixed[field], of("step")[field], "{field}: render vs sweep");
        assert_eq!(sim[field], of("cycle")[field], "{field}: sim vs sweep");
    }
    // The cycle model issues what the functional model steps, plus the samples issued while a
    // ray's ERT signal was on its way back (discarded, never composited).
    let discarded = sim["discarded_after_ert"].as_u64().unwrap();
    let u = |v: &serde_json::Value| v.as_u64().unwrap();
    assert_eq!(u(&sim["samples"]), u(&fixed["samples"]) + discarded);
    assert_eq!(u(&sim["steps"]), u(&fixed["steps"]) + discarded);
    assert_eq!(sim["leaps"], fixed["leaps"]);
    assert_eq!(sim["rays_terminated_early"], fixed["rays_terminated_early"]);
    for field in ["cycles", "row_hits", "row_misses", "discarded_after_ert"] {
        assert!(sim[field].is_u64(), "{field}");
        assert_eq!(sim[field], of("cycle")[field], "{field}: sim vs sweep");
    }
    assert_eq!(fixed["fps"], of("step")["fps"]);
    assert_eq!(sim["fps"], of("cycle")["fps"]);
    assert_eq!(
        pixels(&fixed_png),
        pixels(&sim_png),
        "fixed image == cycle image"
    );
    // The same run description, so the same resolved hardware.
    assert_eq!(sim["run"]["hardware"], fixed["run"]["hardware"]);
}

#[test]
fn the_default_is_the_calibrated_preset_and_overrides_are_printed() {
    let dir = scratch("resolved");
    let png = dir.join("a.png");
    let out = vizsim(&[
        "sim",
        "--dataset",
        "phantom:sphere:16",
        "--size",
        "8x8",
        "-o",
        png.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("no field changed"), "{stdout}");
    assert!(stdout.contains("lagging-first ray selection"), "{stdout}");
    assert!(stdout.contains("row hits"), "{stdout}");
    assert!(stdout.contains("ns per voxel access"), "{stdout}");
    assert!(stdout.contains("no leaping"), "{stdout}");
    let out = vizsim(&[
        "sim",
        "--dataset",
        "phantom:sphere:16",
        "--size",
        "8x8",
        "--set",
        "ray_queue.selection=\"round-robin\"",
        "--subcube",
        "4",
        "-o",
        png.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("ray_queue.selection = \"round-robin\"")
            && stdout.contains("occupancy.subcube = 4"),
        "{stdout}"
    );
    assert!(stdout.contains("round-robin ray selection"), "{stdout}");
    assert!(stdout.contains("leaping 4³ class map"), "{stdout}");
}

#[test]
fn sim_writes_a_command_trace_that_passes_the_checker_and_a_vcd_at_its_clock() {
    let dir = scratch("trace");
    let (trace, vcd, json_path) = (dir.join("t.csv.gz"), dir.join("w.vcd"), dir.join("s.json"));
    vizsim(&[
        "sim",
        "--dataset",
        "phantom:metaballs:32",
        "--size",
        "16x16",
        "--set",
        "clock.frequency_mhz=133.0",
        "--command-trace",
        trace.to_str().unwrap(),
        "--vcd",
        vcd.to_str().unwrap(),
        "--vcd-cycles",
        "0..500",
        "--json",
        json_path.to_str().unwrap(),
    ]);
    let report = vizsim::arch::command_trace::check(&trace).expect("a legal trace");
    let sim = json(&json_path);
    // Every READ of the frame is in the trace (index 1: READ).
    assert_eq!(
        report.commands[1],
        sim["row_hits"].as_u64().unwrap() + sim["row_misses"].as_u64().unwrap()
    );
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(text.contains("$timescale"), "a VCD");
    assert!(text.contains("clk"), "a clock signal");
    assert!(
        !text.contains("10 ns"),
        "the timescale follows 133 MHz, not the fixed 10 ns"
    );
    // No trace with the ideal memory: it issues no commands.
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args([
            "sim",
            "--dataset",
            "phantom:sphere:16",
            "--memory",
            "ideal",
            "--command-trace",
            dir.join("x.csv").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(!dir.join("x.csv").exists());
}
