//! Generated phantoms: spec parsing, determinism and the documented value design.

use std::collections::VecDeque;
use std::ops::RangeInclusive;

use proptest::prelude::*;
use vizsim::volume::phantom::{generate, parse_spec, PhantomKind, PhantomSpec, SIZE_RANGE};
use vizsim::volume::Volume;
use vizsim::Error;

fn spec(kind: PhantomKind, size: usize, seed: u64, time: f32) -> PhantomSpec {
    PhantomSpec {
        kind,
        size,
        seed,
        time,
    }
}

#[test]
fn every_kind_parses_and_generates_at_size_32() {
    for kind in PhantomKind::ALL {
        let parsed = parse_spec(&format!("{}:32", kind.name())).unwrap();
        assert_eq!(parsed, spec(kind, 32, 1, 0.0));
        let volume = generate(&parsed);
        assert_eq!(volume.name, format!("phantom:{}:32", kind.name()));
        assert_eq!(volume.dims, [32; 3]);
        assert_eq!(volume.spacing, [1.0; 3]);
        assert_eq!(volume.bits, 8);
        assert!(volume.data.iter().all(|&v| v <= 255));
    }
}

#[test]
fn generation_is_deterministic_across_runs_and_thread_counts() {
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for kind in PhantomKind::ALL {
        let spec = spec(kind, 32, 5, 0.3);
        let first = generate(&spec);
        assert_eq!(first.data, generate(&spec).data, "{kind:?} rerun");
        let serial = one_thread.install(|| generate(&spec));
        assert_eq!(first.data, serial.data, "{kind:?} with one thread");
    }
}

/// The value design documented on `PhantomKind`.
struct Design {
    kind: PhantomKind,
    occupied_percent: RangeInclusive<f64>,
    max: RangeInclusive<u16>,
}

const DESIGN: [Design; 5] = [
    Design {
        kind: PhantomKind::Sphere,
        occupied_percent: 25.0..=29.0,
        max: 240..=250,
    },
    Design {
        kind: PhantomKind::Shells,
        occupied_percent: 10.0..=22.0,
        max: 220..=220,
    },
    Design {
        kind: PhantomKind::Jet,
        occupied_percent: 5.0..=12.0,
        max: 200..=255,
    },
    Design {
        kind: PhantomKind::Metaballs,
        occupied_percent: 5.0..=20.0,
        max: 160..=255,
    },
    Design {
        kind: PhantomKind::Cast,
        occupied_percent: 12.0..=25.0,
        max: 180..=186,
    },
];

#[test]
fn occupancy_and_peak_are_in_documented_ranges() {
    for design in DESIGN {
        let kind = design.kind;
        for size in [32, 64] {
            for seed in 1..=3 {
                let info = generate(&spec(kind, size, seed, 0.0)).info();
                assert!(
                    design.occupied_percent.contains(&info.occupied_percent),
                    "{kind:?} size {size} seed {seed}: occupied {}%",
                    info.occupied_percent
                );
                assert!(
                    design.max.contains(&info.max),
                    "{kind:?} size {size} seed {seed}: max {}",
                    info.max
                );
                assert_eq!(info.min, 0, "{kind:?} has empty space");
            }
        }
    }
}

#[test]
fn jet_is_sparse_like_the_fuel_dataset() {
    for size in [32, 64, 128] {
        for seed in 1..=3 {
            let occupied = generate(&spec(PhantomKind::Jet, size, seed, 0.0))
                .info()
                .occupied_percent;
            assert!(
                (5.0..=12.0).contains(&occupied),
                "size {size} seed {seed}: {occupied}%"
            );
        }
    }
}

#[test]
fn jet_is_densest_at_the_nozzle_face() {
    let volume = generate(&spec(PhantomKind::Jet, 64, 1, 0.0));
    let slice_max = |z: usize| -> u16 {
        (0..64 * 64)
            .map(|i| volume.get(i % 64, i / 64, z))
            .max()
            .unwrap()
    };
    assert!(slice_max(0) >= 200, "nozzle {}", slice_max(0));
    assert!(
        slice_max(63) < slice_max(0) / 2,
        "far face {}",
        slice_max(63)
    );
}

#[test]
fn sphere_is_exactly_zero_outside_its_radius() {
    let n = 64;
    let volume = generate(&spec(PhantomKind::Sphere, n, 1, 0.0));
    let (centre, radius) = ((n - 1) as f64 / 2.0, 0.4 * n as f64);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let d2 = [x, y, z]
                    .map(|c| (c as f64 - centre).powi(2))
                    .iter()
                    .sum::<f64>();
                if d2 >= radius * radius {
                    assert_eq!(volume.get(x, y, z), 0, "({x}, {y}, {z})");
                }
            }
        }
    }
}

#[test]
fn shells_hold_only_their_three_values() {
    let volume = generate(&spec(PhantomKind::Shells, 64, 1, 0.0));
    let mut seen = [false; 256];
    for &v in &volume.data {
        seen[v as usize] = true;
    }
    let values: Vec<usize> = (0..256).filter(|&v| seen[v]).collect();
    assert_eq!(values, [0, 60, 130, 220]);
}

/// Voxels below this are air-like (the cast's metal is 174..=186).
const AIR_BELOW: u16 = 90;

#[test]
fn cast_air_is_exactly_zero_beyond_two_voxels_of_the_part() {
    let volume = generate(&spec(PhantomKind::Cast, 64, 1, 0.0));
    let n = 64;
    let (mut low, mut high) = ([n; 3], [0; 3]);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                if volume.get(x, y, z) >= AIR_BELOW {
                    for (axis, c) in [x, y, z].into_iter().enumerate() {
                        low[axis] = low[axis].min(c);
                        high[axis] = high[axis].max(c);
                    }
                }
            }
        }
    }
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let near_part = [x, y, z]
                    .into_iter()
                    .enumerate()
                    .all(|(axis, c)| c + 2 >= low[axis] && c <= high[axis] + 2);
                if !near_part {
                    assert_eq!(volume.get(x, y, z), 0, "({x}, {y}, {z})");
                }
            }
        }
    }
}

/// Connected groups (6-neighbourhood) of air-like voxels that the outside air cannot reach:
/// the blowholes. Returns, per group, its voxel count and its lowest value.
fn enclosed_voids(volume: &Volume) -> Vec<(usize, u16)> {
    let n = volume.dims[0];
    let air = |i: usize| volume.data[i] < AIR_BELOW;
    let neighbours = move |i: usize| {
        let (x, y, z) = (i % n, i / n % n, i / (n * n));
        let mut out = Vec::with_capacity(6);
        for (c, step) in [(x, 1), (y, n), (z, n * n)] {
            if c > 0 {
                out.push(i - step);
            }
            if c + 1 < n {
                out.push(i + step);
            }
        }
        out
    };
    let mut visited = vec![false; volume.data.len()];
    let flood = |start: usize, visited: &mut Vec<bool>| -> (usize, u16) {
        let (mut count, mut lowest) = (0, u16::MAX);
        let mut queue = VecDeque::from([start]);
        visited[start] = true;
        while let Some(i) = queue.pop_front() {
            count += 1;
            lowest = lowest.min(volume.data[i]);
            for j in neighbours(i) {
                if air(j) && !visited[j] {
                    visited[j] = true;
                    queue.push_back(j);
                }
            }
        }
        (count, lowest)
    };
    // Air connected to the volume's faces is outside (including the bore).
    for i in 0..volume.data.len() {
        let on_face = neighbours(i).len() < 6;
        if on_face && air(i) && !visited[i] {
            flood(i, &mut visited);
        }
    }
    let mut voids = Vec::new();
    for i in 0..volume.data.len() {
        if air(i) && !visited[i] {
            voids.push(flood(i, &mut visited));
        }
    }
    voids
}

#[test]
fn cast_has_blowholes_enclosed_in_metal() {
    for seed in 1..=3 {
        let voids = enclosed_voids(&generate(&spec(PhantomKind::Cast, 64, seed, 0.0)));
        assert!(
            (8..=20).contains(&voids.len()),
            "seed {seed}: {} blowholes",
            voids.len()
        );
        for (count, lowest) in voids {
            assert_eq!(lowest, 0, "seed {seed}: blowhole core is air");
            // Radius 2..4 voxels: a few to a few hundred voxels.
            assert!((1..=400).contains(&count), "seed {seed}: {count} voxels");
        }
    }
    let small = enclosed_voids(&generate(&spec(PhantomKind::Cast, 32, 1, 0.0)));
    assert!(!small.is_empty(), "size 32 still has a blowhole");
}

#[test]
fn metaballs_move_with_time_and_repeat_at_equal_time() {
    let at = |time| generate(&spec(PhantomKind::Metaballs, 32, 1, time)).data;
    assert_ne!(at(0.0), at(0.5));
    assert_eq!(at(0.5), at(0.5));
    let parsed = generate(&parse_spec("metaballs:32:t=0.5").unwrap());
    assert_eq!(parsed.data, at(0.5));
    assert_eq!(parsed.name, "phantom:metaballs:32:t=0.5");
}

#[test]
fn seed_changes_only_seeded_phantoms() {
    for kind in PhantomKind::ALL {
        let one = generate(&spec(kind, 32, 1, 0.0)).data;
        let two = generate(&spec(kind, 32, 2, 0.0)).data;
        let seeded = !matches!(kind, PhantomKind::Sphere | PhantomKind::Shells);
        assert_eq!(one != two, seeded, "{kind:?}");
    }
}

#[test]
fn parse_spec_accepts_the_documented_forms() {
    use PhantomKind::*;
    let cases = [
        ("sphere", spec(Sphere, 64, 1, 0.0)),
        ("sphere:64", spec(Sphere, 64, 1, 0.0)),
        ("metaballs:64:t=0.5", spec(Metaballs, 64, 1, 0.5)),
        ("cast:128:seed=7", spec(Cast, 128, 7, 0.0)),
        ("jet:seed=3", spec(Jet, 64, 3, 0.0)),
        ("metaballs:8:t=-2:seed=9", spec(Metaballs, 8, 9, -2.0)),
        ("shells:512", spec(Shells, 512, 1, 0.0)),
    ];
    for (text, expected) in cases {
        assert_eq!(parse_spec(text).unwrap(), expected, "{text}");
    }
    assert_eq!(PhantomSpec::default_for(Cast), spec(Cast, 64, 1, 0.0));
    assert_eq!(spec(Cast, 128, 7, 0.0).name(), "phantom:cast:128:seed=7");
    assert_eq!(spec(Sphere, 64, 7, 0.5).name(), "phantom:sphere:64");
}

#[test]
fn parse_spec_errors_name_the_bad_part() {
    let cases: [(&str, &[&str]); 13] = [
        (
            "cubes:64",
            &["cubes", "sphere", "shells", "jet", "metaballs", "cast"],
        ),
        ("", &["unknown kind", "sphere"]),
        ("sphere:7", &["size 7", "8..=512"]),
        ("sphere:513", &["size 513", "8..=512"]),
        ("sphere:big", &["`big`"]),
        ("sphere:64:foo=1", &["`foo`", "seed, t"]),
        ("sphere:64:64", &["`64`"]),
        ("cast:64:seed=-1", &["seed=-1"]),
        ("metaballs:64:t=nan", &["t=nan"]),
        ("metaballs:64:t=1:t=2", &["`t` given twice"]),
        ("sphere:", &["size ``"]),
        ("sphere:16:t=1", &["`t=1`", "t= applies to metaballs, tsdf"]),
        (
            "shells:seed=3",
            &["`seed=3`", "seed= applies to jet, metaballs, cast"],
        ),
    ];
    for (text, needles) in cases {
        let error = parse_spec(text).unwrap_err();
        assert!(matches!(error, Error::Invalid(_)), "{text}: {error:?}");
        let message = error.to_string();
        for needle in needles {
            assert!(
                message.contains(needle),
                "{text}: `{message}` lacks {needle}"
            );
        }
    }
}

#[test]
#[should_panic(expected = "size 7 out of range")]
fn generate_rejects_an_out_of_range_size() {
    generate(&spec(PhantomKind::Sphere, 7, 1, 0.0));
}

proptest! {
    #[test]
    fn canonical_name_parses_back_to_the_same_volume(
        kind in prop::sample::select(PhantomKind::ALL.to_vec()),
        size in SIZE_RANGE,
        seed in any::<u64>(),
        time in -1e3f32..1e3,
    ) {
        let original = spec(kind, size, seed, time);
        let name = original.name();
        let parsed = parse_spec(name.strip_prefix("phantom:").unwrap()).unwrap();
        prop_assert_eq!(parsed.name(), name);
        prop_assert_eq!((parsed.kind, parsed.size), (kind, size));
        if kind == PhantomKind::Metaballs {
            prop_assert_eq!(parsed.time, time);
        }
        if !matches!(kind, PhantomKind::Sphere | PhantomKind::Shells) {
            prop_assert_eq!(parsed.seed, seed);
        }
    }
}
