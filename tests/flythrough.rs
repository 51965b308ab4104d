//! Fly-through and interleaved sampling (issue 15, parts 3 and 4), through the one run path
//! (`run::prepare` / `run::execute`):
//!
//! - a camera inside the volume (inside the empty lumen of `phantom:tube` and inside its
//!   occupied wall, perspective and orthographic): the cycle image equals the functional
//!   image, and every leaping structure (occupancy map, distance volume, bricks) equals no
//!   leaping bit for bit;
//! - interleaved sampling: the cycle image equals the functional image; off is the plain image;
//! - camera paths: keys hit exactly at their frames, interpolation, bad input.

mod common;

use glam::Vec3;
use vizsim::camera::{interleave_offset, Projection, View};
use vizsim::config::HardwareConfig;
use vizsim::path::CameraPath;
use vizsim::run::{execute, prepare, Model, Probes, RunDescription, RunReport};
use vizsim::volume::Volume;

const SIZE: u32 = 32;

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-flythrough-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Writes `text` to a file of its own: tests run in parallel and several write the same
/// path names, so each call gets a numbered name (a shared name raced: one test read a file
/// another had just truncated).
fn write(name: &str, text: &str) -> String {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = scratch(&format!("{n}-{name}"));
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

fn render(
    volume: &Volume,
    model: Model,
    view: &str,
    projection: Projection,
    sets: &[&str],
) -> RunReport {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let config = HardwareConfig::load(None, &sets).unwrap();
    let mut run = RunDescription::new(&volume.name, "class", model, config);
    run.size = (SIZE, SIZE);
    run.view = view.to_string();
    run.projection = projection;
    let prepared = prepare(&run, volume).unwrap_or_else(|e| panic!("{sets:?}: {e}"));
    execute(&run, &prepared, Probes::default()).unwrap_or_else(|e| panic!("{sets:?}: {e}"))
}

/// Largest difference of a colour channel between two frames.
fn max_diff(a: &RunReport, b: &RunReport) -> u8 {
    let c = vizsim::compare::compare(&a.frame.pixels, &b.frame.pixels, SIZE, SIZE).unwrap();
    c.max_abs_error[..3].iter().copied().max().unwrap()
}

fn tube() -> Volume {
    vizsim::volume::dataset::load("phantom:tube:32", None).unwrap()
}

/// A two-key path whose eye stays at `eye` (fractions of the extent), looking along +y.
fn still_path(name: &str, eye: [f32; 3]) -> String {
    let [x, y, z] = eye;
    write(
        name,
        &format!(
            "units = \"extent\"\nfov_y_deg = 70.0\nview_width = 0.4\n\
             [[key]]\neye = [{x}, {y}, {z}]\nlook_at = [{x}, {}, {z}]\nup = [0.0, 0.0, 1.0]\n\
             [[key]]\neye = [{x}, {}, {z}]\nlook_at = [{x}, {}, {z}]\nup = [0.0, 0.0, 1.0]\n",
            y + 0.2,
            y + 0.05,
            y + 0.25
        ),
    )
}

/// The voxel nearest a point given in fractions of the extent.
fn value_at(volume: &Volume, fraction: [f32; 3]) -> u16 {
    let p = [0, 1, 2].map(|a| (fraction[a] * (volume.dims[a] - 1) as f32).round() as usize);
    volume.get(p[0], p[1], p[2])
}

/// (view, what): a camera in the tube's empty lumen and one inside its occupied wall.
fn inside_views(volume: &Volume) -> Vec<(String, &'static str)> {
    let (cx, cz) = vizsim::volume::phantom::tube_centre(0.3);
    let lumen = [cx as f32, 0.3, cz as f32];
    let wall = [cx as f32 + 0.18, 0.3, cz as f32];
    assert_eq!(
        value_at(volume, lumen),
        0,
        "the lumen camera must sit in empty space"
    );
    assert!(
        value_at(volume, wall) > 100,
        "the wall camera must sit in the wall"
    );
    vec![
        (
            format!("path:{}:0/4", still_path("lumen.toml", lumen)),
            "lumen",
        ),
        (
            format!("path:{}:0/4", still_path("wall.toml", wall)),
            "wall",
        ),
        // The ready path: frame 30 of 120 is inside the lumen.
        (
            "path:configs/paths/tube.toml:30/120".to_string(),
            "ready path",
        ),
    ]
}

#[test]
fn a_camera_inside_starts_its_rays_at_the_near_plane() {
    let volume = tube();
    for (view, what) in inside_views(&volume) {
        let report = render(&volume, Model::Step, &view, Projection::Persp, &[]);
        // Every ray starts at the eye (t = 0, k = 0): the eye is inside the box.
        assert!(
            report
                .frame
                .rays
                .iter()
                .all(|r| r.hit && r.first_sample == 0 && r.t_enter == 0.0),
            "{what}: a ray did not start at the eye"
        );
        let float = render(&volume, Model::Float, &view, Projection::Persp, &[]);
        let diff = max_diff(&float, &report);
        assert!(diff <= 8, "{what}: float vs fixed max diff {diff}");
    }
}

#[test]
fn cycle_image_equals_functional_image_inside_and_interleaved() {
    let volume = tube();
    let mut views = inside_views(&volume);
    views.push(("orbit:5/72".to_string(), "outside"));
    for (view, what) in &views {
        for projection in [Projection::Persp, Projection::Ortho] {
            for sets in [
                &[][..],
                &["ray.interleave=4"][..],
                &["ray.interleave=3", "occupancy.subcube=4"][..],
                &["bricks.size=8"][..],
            ] {
                let step = render(&volume, Model::Step, view, projection, sets);
                let cycle = render(&volume, Model::Cycle, view, projection, sets);
                assert!(
                    step.frame.pixels == cycle.frame.pixels,
                    "{what} {projection:?} {sets:?}: cycle image differs from the functional image"
                );
                assert!(step.stats.samples > 0, "{what} {projection:?}: no samples");
            }
        }
    }
}

#[test]
fn leaping_from_inside_equals_no_leaping() {
    let volume = tube();
    for (view, what) in inside_views(&volume) {
        for projection in [Projection::Persp, Projection::Ortho] {
            let plain = render(&volume, Model::Step, &view, projection, &[]);
            for sets in [
                &["occupancy.subcube=2"][..],
                &["occupancy.subcube=4"][..],
                &["occupancy.subcube=2", "occupancy.hierarchy=true"][..],
                &["occupancy.subcube=4", "occupancy.kind=class"][..],
                &["occupancy.structure=distance"][..],
                &["bricks.size=4"][..],
                &["bricks.size=8", "occupancy.subcube=4"][..],
                &["occupancy.subcube=4", "ray.interleave=2"][..],
            ] {
                let leap = render(&volume, Model::Step, &view, projection, sets);
                let interleaved;
                let reference = if sets.contains(&"ray.interleave=2") {
                    interleaved = render(
                        &volume,
                        Model::Step,
                        &view,
                        projection,
                        &["ray.interleave=2"],
                    );
                    &interleaved
                } else {
                    &plain
                };
                assert!(
                    leap.frame.pixels == reference.frame.pixels,
                    "{what} {projection:?} {sets:?}: leaping changed the image"
                );
                let saved = leap.stats.leaps
                    + leap.stats.skipped
                    + leap
                        .frame
                        .rays
                        .iter()
                        .map(|r| r.positions_cut as u64)
                        .sum::<u64>();
                assert!(
                    saved > 0,
                    "{what} {projection:?} {sets:?}: nothing leapt or cut"
                );
            }
        }
    }
}

#[test]
fn interleaving_shifts_first_samples_and_off_is_the_plain_image() {
    let volume = tube();
    // The pattern holds every offset i/N² once.
    for n in [1u32, 2, 3, 4, 8] {
        let mut ranks: Vec<u32> = (0..n)
            .flat_map(|y| (0..n).map(move |x| (x, y)))
            .map(|(x, y)| {
                let o = interleave_offset(x, y, n);
                assert!((0.0..1.0).contains(&o));
                (o * (n * n) as f32).round() as u32
            })
            .collect();
        ranks.sort();
        assert_eq!(ranks, (0..n * n).collect::<Vec<_>>(), "N = {n}");
        assert_eq!(
            interleave_offset(5, 7, n),
            interleave_offset(5 + n, 7 + 2 * n, n)
        );
    }
    for model in [Model::Float, Model::Step] {
        let plain = render(&volume, model, "orbit:5/72", Projection::Ortho, &[]);
        let one = render(
            &volume,
            model,
            "orbit:5/72",
            Projection::Ortho,
            &["ray.interleave=1"],
        );
        let four = render(
            &volume,
            model,
            "orbit:5/72",
            Projection::Ortho,
            &["ray.interleave=4"],
        );
        assert!(plain.frame.pixels == one.frame.pixels, "{model:?}");
        assert!(plain.frame.pixels != four.frame.pixels, "{model:?}");
        // Float and fixed agree with interleaving as without.
        if model == Model::Step {
            let float = render(
                &volume,
                Model::Float,
                "orbit:5/72",
                Projection::Ortho,
                &["ray.interleave=4"],
            );
            let diff = max_diff(&float, &four);
            assert!(diff <= 8, "max diff {diff}");
        }
    }
    // The run key is unchanged when off.
    let config = HardwareConfig::load(None, &["ray.interleave=1".to_string()]).unwrap();
    let text = toml::to_string(&config).unwrap();
    assert!(!text.contains("interleave"), "{text}");
}

#[test]
fn path_keys_are_hit_exactly_at_their_frames() {
    let text = "units = \"world\"\ninterpolation = \"catmull-rom\"\n\
        [[key]]\neye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 1.0, 0.0]\nup = [0.0, 0.0, 1.0]\n\
        [[key]]\neye = [1.3, 2.7, 0.1]\nlook_at = [2.0, 3.0, 0.3]\nup = [0.1, 0.0, 1.0]\n\
        [[key]]\neye = [3.0, 2.9, -0.4]\nlook_at = [3.3, 5.0, 0.0]\nup = [0.0, 0.3, 1.0]\n\
        [[key]]\neye = [4.1, 7.0, 1.0]\nlook_at = [4.0, 9.0, 1.0]\nup = [0.0, 0.0, 1.0]\n";
    for interpolation in ["catmull-rom", "linear"] {
        let text = text.replace("catmull-rom", interpolation);
        let path = CameraPath::parse(&text, "keys.toml").unwrap();
        // 4 keys over 10 frames: key i is frame 3i.
        for (i, key) in path.keys.iter().enumerate() {
            let pose = path.pose(3 * i as u32, 10).unwrap();
            assert_eq!(pose.eye, Vec3::from(key.eye), "{interpolation} key {i}");
            assert_eq!(
                pose.look_at,
                Vec3::from(key.look_at),
                "{interpolation} key {i}"
            );
        }
        // Between keys: continuous, and up is a unit vector perpendicular to the direction.
        let mut last = path.pose(0, 100).unwrap().eye;
        for k in 1..100 {
            let pose = path.pose(k, 100).unwrap();
            assert!(
                pose.eye.distance(last) < 0.3,
                "{interpolation} frame {k} jumps"
            );
            last = pose.eye;
            let dir = (pose.look_at - pose.eye).normalize();
            assert!(pose.up.dot(dir).abs() < 1e-5 && (pose.up.length() - 1.0).abs() < 1e-5);
        }
    }
    // Linear: the middle frame of two keys is their midpoint.
    let path = CameraPath::parse(&text.replace("catmull-rom", "linear"), "keys.toml").unwrap();
    let mid = path.pose(1, 7).unwrap(); // u = 0.5
    assert!(
        mid.eye.distance(Vec3::new(0.65, 1.35, 0.05)) < 1e-6,
        "{}",
        mid.eye
    );
    // The camera of a key frame is at the key, scaled by the extent ("extent" units).
    let file = still_path("scaled.toml", [0.25, 0.5, 0.75]);
    let view = View::parse(&format!("path:{file}:0/3")).unwrap();
    let camera = vizsim::camera::Camera::for_volume(
        Vec3::new(10.0, 20.0, 40.0),
        view,
        Projection::Persp,
        8,
        8,
    )
    .unwrap();
    assert_eq!(camera.eye, Vec3::new(2.5, 10.0, 30.0));
}

#[test]
fn bad_paths_give_clear_errors() {
    let key = |eye: &str, look: &str, up: &str| {
        format!("[[key]]\neye = {eye}\nlook_at = {look}\nup = {up}\n")
    };
    let err = |name: &str, text: &str, frame: &str| -> String {
        let file = write(name, text);
        let e = View::parse(&format!("path:{file}:{frame}"))
            .expect_err("refused")
            .to_string();
        assert!(e.contains(&file), "{e} does not name {file}");
        e
    };
    let good = key("[0.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", "[0.0, 0.0, 1.0]");
    // Fewer than two keys.
    let e = err("one.toml", &good, "0/2");
    assert!(e.contains("key") && e.contains("two"), "{e}");
    let e = err("none.toml", "units = \"world\"\n", "0/2");
    assert!(e.contains("key"), "{e}");
    // Up parallel to the view direction at a key.
    let bad_key = key("[0.0, 0.0, 0.0]", "[0.0, 0.0, 1.0]", "[0.0, 0.0, 2.0]");
    let e = err("parallel-key.toml", &format!("{good}{bad_key}"), "0/2");
    assert!(e.contains("key[1]") && e.contains("parallel"), "{e}");
    // Up parallel to the view direction between keys (frame 1 of 3 looks straight up).
    let turn = key("[0.0, 0.0, 0.0]", "[-1.0, 0.0, 1.0]", "[0.0, 0.0, 1.0]");
    let first = key("[0.0, 0.0, 0.0]", "[1.0, 0.0, 0.0]", "[0.0, 0.0, 1.0]");
    let text = format!("interpolation = \"linear\"\n{first}{turn}");
    let e = err("parallel-frame.toml", &text, "1/3");
    assert!(e.contains("frame 1 of 3") && e.contains("parallel"), "{e}");
    // Opposite up vectors: zero half way between them (it read "up [NaN, NaN, NaN] is
    // parallel to the view direction").
    let down = key("[0.0, -1.0, 0.0]", "[0.0, 1.0, 0.0]", "[0.0, 0.0, -1.0]");
    let text = format!("interpolation = \"linear\"\n{good}{down}");
    let e = err("opposite-up.toml", &text, "1/3");
    assert!(
        e.contains("key[0] and key[1] point opposite ways") && !e.contains("NaN"),
        "{e}"
    );
    // Eye equals look-at.
    let same = key("[1.0, 1.0, 1.0]", "[1.0, 1.0, 1.0]", "[0.0, 0.0, 1.0]");
    let e = err("same.toml", &format!("{good}{same}"), "0/2");
    assert!(e.contains("key[1]") && e.contains("coincide"), "{e}");
    // An eye so far out that f32 poses would merge it with its look-at.
    let far = key("[1e30, 0.0, 0.0]", "[0.0, 0.0, 0.0]", "[0.0, 0.0, 1.0]");
    let e = err("far.toml", &format!("{good}{far}"), "0/2");
    assert!(e.contains("key[1].eye") && e.contains("within"), "{e}");
    // Malformed TOML, an unknown field, a wrong type, a bad setting.
    let e = err("malformed.toml", "[[key]\neye = ", "0/2");
    assert!(e.contains("camera path"), "{e}");
    let e = err(
        "unknown.toml",
        &format!("{good}{}", good.replace("eye =", "eyes =")),
        "0/2",
    );
    assert!(e.contains("eyes"), "{e}");
    let e = err(
        "short.toml",
        &format!(
            "{good}{}",
            key("[1.0, 2.0]", "[0.0, 1.0, 0.0]", "[0.0, 0.0, 1.0]")
        ),
        "0/2",
    );
    assert!(
        e.contains("eye") || e.contains("length") || e.contains("3"),
        "{e}"
    );
    let e = err(
        "fov.toml",
        &format!("fov_y_deg = 180.0\n{good}{good}"),
        "0/2",
    );
    assert!(e.contains("fov_y_deg"), "{e}");
    let e = err(
        "interp.toml",
        &format!("interpolation = \"cubic\"\n{good}{good}"),
        "0/2",
    );
    assert!(e.contains("interpolation") || e.contains("cubic"), "{e}");
    // K out of range, malformed K/N, a missing file.
    let file = write("ok.toml", &format!("{good}{good}"));
    for spec in ["2/2", "0/0", "x/2", "2", "-1/4"] {
        let e = View::parse(&format!("path:{file}:{spec}"))
            .expect_err(spec)
            .to_string();
        assert!(e.contains("path:"), "{spec}: {e}");
    }
    // A whole number of frames too large is out of range, not malformed.
    let e = View::parse(&format!("path:{file}:0/100000000000000"))
        .expect_err("too many frames")
        .to_string();
    assert!(
        e.contains("out of range") && !e.contains("not a whole"),
        "{e}"
    );
    assert!(View::parse(&format!("path:{file}:1/2")).is_ok());
    let missing = scratch("missing.toml").display().to_string();
    let e = View::parse(&format!("path:{missing}:0/2"))
        .expect_err("missing")
        .to_string();
    assert!(e.contains(&missing), "{e}");
    // Interleaving pattern of 0.
    let e = HardwareConfig::load(None, &["ray.interleave=0".to_string()])
        .expect_err("refused")
        .to_string();
    assert!(e.contains("ray.interleave"), "{e}");
    // The run path refuses a bad path view before rendering.
    let volume = tube();
    let mut run = RunDescription::new(
        &volume.name,
        "class",
        Model::Step,
        HardwareConfig::load(None, &[]).unwrap(),
    );
    run.view = format!("path:{missing}:0/2");
    assert!(run.validate().is_err());
}

#[test]
fn experiment_files_take_a_camera_path() {
    use vizsim::experiment::spec::expand;
    let text = r#"
name = "flythrough"
datasets = ["phantom:tube:16"]
tf = ["class"]
modes = ["ert", "ert+leap4"]
models = ["step"]
[frames]
orbit = 8
every = 4
size = "16x16"
projection = "persp"
path = "configs/paths/tube.toml"
"#;
    let expansion = expand(text, "test", None).unwrap();
    let views: Vec<&str> = expansion.runs.iter().map(|r| r.run.view.as_str()).collect();
    assert_eq!(views.len(), 4, "{views:?}");
    for v in &views {
        assert!(
            v.starts_with("path:configs/paths/tube.toml:") && v.ends_with("/8"),
            "{v}"
        );
    }
    // Without `path` the views are the orbit's, and the key is unchanged.
    let orbit = expand(
        &text.replace("path = \"configs/paths/tube.toml\"\n", ""),
        "test",
        None,
    )
    .unwrap();
    assert!(orbit.runs.iter().all(|r| r.run.view.starts_with("orbit:")));
    assert!(!toml::to_string(&orbit.experiment).unwrap().contains("path"));
    // A bad path file is an error naming frames.path.
    let e = match expand(&text.replace("tube.toml", "no-such.toml"), "test", None) {
        Ok(_) => panic!("a missing path file was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("frames.path") && e.contains("no-such.toml"),
        "{e}"
    );
    // The runs render through the one run path.
    let volume = vizsim::volume::dataset::load("phantom:tube:16", None).unwrap();
    let run = &expansion.runs[1].run;
    let prepared = prepare(run, &volume).unwrap();
    let report = execute(run, &prepared, Probes::default()).unwrap();
    assert!(report.stats.samples > 0);
}

#[test]
fn render_and_sim_accept_a_path_view() {
    let bin = env!("CARGO_BIN_EXE_vizsim");
    for (cmd, extra) in [("render", &["--model", "fixed"][..]), ("sim", &[][..])] {
        let out = scratch(&format!("{cmd}.png"));
        let status = std::process::Command::new(bin)
            .args([cmd, "--dataset", "phantom:tube:16", "--size", "16x16"])
            .args([
                "--projection",
                "persp",
                "--view",
                "path:configs/paths/tube.toml:3/10",
            ])
            .args(["--set", "ray.interleave=2", "-o"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(
            status.status.success(),
            "{cmd}: {}",
            String::from_utf8_lossy(&status.stderr)
        );
        assert!(out.exists(), "{cmd}");
        let bad = std::process::Command::new(bin)
            .args([cmd, "--dataset", "phantom:tube:16", "--size", "16x16"])
            .args(["--view", "path:configs/paths/tube.toml:10/10", "-o"])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            !bad.status.success() && err.contains("10 of 10"),
            "{cmd}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// An orthographic path camera without `view_width` sees the volume's largest extent in either
/// unit: a world-unit path defaulted to 1, one voxel, and an orthographic fly-through showed a
/// uniform colour without a word (a review). A given width is taken in the path's units.
#[test]
fn an_orthographic_path_camera_sees_the_volume_by_default_in_either_unit() {
    let keys = |units: &str, width: &str| {
        format!(
            "units = \"{units}\"\n{width}\
             [[key]]\neye = [0.5, -1.0, 0.5]\nlook_at = [0.5, 0.5, 0.5]\nup = [0.0, 0.0, 1.0]\n\
             [[key]]\neye = [0.6, -1.0, 0.5]\nlook_at = [0.6, 0.5, 0.5]\nup = [0.0, 0.0, 1.0]\n"
        )
    };
    let extent = Vec3::new(64.0, 48.0, 32.0);
    let width_of = |text: &str| {
        CameraPath::parse(text, "p.toml")
            .unwrap()
            .camera(extent, 0, 2, Projection::Ortho, 16, 16)
            .unwrap()
            .view_width
    };
    assert_eq!(width_of(&keys("world", "")), 64.0);
    assert_eq!(width_of(&keys("extent", "")), 64.0);
    assert_eq!(width_of(&keys("world", "view_width = 20.0\n")), 20.0);
    assert_eq!(width_of(&keys("extent", "view_width = 0.25\n")), 16.0);
}
