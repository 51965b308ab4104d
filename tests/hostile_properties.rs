//! Structure-aware property tests of the TOML inputs (issue 17, "Tests that stay"): hardware
//! configurations, transfer functions, experiment files and camera paths are generated as TOML
//! documents of the right shape with hostile values (extremes, NaN, infinities, wrong types,
//! empty or deeply nested tables and arrays, missing and extra keys), or as valid documents cut
//! or spliced, and fed to the library's parse-and-validate functions in-process. Whatever they
//! get, they must return (Ok or a clean error): never panic, never take more than `BOUND`.

use std::sync::mpsc;
use std::time::Duration;

use proptest::prelude::*;
use toml::Value;

use vizsim::config::HardwareConfig;
use vizsim::experiment::spec;
use vizsim::path::CameraPath;
use vizsim::transfer::TransferFunction;

/// A case that runs longer is a hang.
const BOUND: Duration = Duration::from_secs(10);

/// Runs `f` on its own thread and fails the case if it panics or does not finish within
/// `BOUND` (the thread is left behind; the test fails anyway).
fn bounded<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    // Requests sized by a hostile value are refused up front, not allocated.
    vizsim::budget::set(256 << 20);
    let (tx, rx) = mpsc::channel();
    let handle = std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(BOUND) {
        Ok(value) => {
            let _ = handle.join();
            value
        }
        Err(mpsc::RecvTimeoutError::Timeout) => panic!("{what}: no answer within {BOUND:?}"),
        Err(mpsc::RecvTimeoutError::Disconnected) => {
            let _ = handle.join();
            panic!("{what}: panicked (see above)")
        }
    }
}

/// A hostile scalar, array or table.
fn hostile_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Integer(0)),
        Just(Value::Integer(-1)),
        Just(Value::Integer(1)),
        Just(Value::Integer(i64::MAX)),
        Just(Value::Integer(i64::MIN)),
        Just(Value::Integer(u32::MAX as i64 + 1)),
        (-70i64..70).prop_map(Value::Integer),
        (0u32..63).prop_map(|e| Value::Integer(1i64 << e)),
        Just(Value::Float(f64::NAN)),
        Just(Value::Float(f64::INFINITY)),
        Just(Value::Float(f64::NEG_INFINITY)),
        Just(Value::Float(-0.0)),
        Just(Value::Float(5e-324)),
        Just(Value::Float(1e-38)),
        Just(Value::Float(3e38)),
        Just(Value::Float(1e308)),
        any::<f64>().prop_map(Value::Float),
        (-100.0f64..100.0).prop_map(Value::Float),
        any::<bool>().prop_map(Value::Boolean),
        Just(Value::String(String::new())),
        "[a-z0-9_.:+-]{0,12}".prop_map(Value::String),
        Just(Value::String("\u{0}\u{202e}é".into())),
        Just(Value::Array(Vec::new())),
        Just(Value::Table(toml::Table::new())),
    ];
    leaf.prop_recursive(6, 24, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            prop::collection::btree_map("[a-z_]{1,8}", inner, 0..3)
                .prop_map(|m| Value::Table(m.into_iter().collect())),
        ]
    })
}

/// A deeply nested array: parsers and serde must not overflow the stack.
fn deep(depth: usize) -> Value {
    (0..depth).fold(Value::Integer(1), |v, _| Value::Array(vec![v]))
}

/// What to do to one field of a valid document.
#[derive(Clone, Debug)]
enum Edit {
    /// A hostile value of the field's own type (an extreme integer for an integer, NaN or a
    /// huge float for a float, an odd string or list of words), so validation, not the
    /// parser, meets it.
    Typed(i64, f64, Value, Vec<Value>),
    Set(Value),
    Remove,
    /// An extra key beside it.
    Extra(String, Value),
    /// The field's whole section replaced.
    SectionTo(Value),
}

fn hostile_int() -> impl Strategy<Value = i64> {
    prop_oneof![
        Just(0i64),
        Just(-1),
        Just(i64::MAX),
        Just(i64::MIN),
        Just(u32::MAX as i64),
        Just(u32::MAX as i64 + 1),
        -3i64..300,
        (0u32..63).prop_map(|e| 1i64 << e),
    ]
}

fn hostile_float() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(0.0),
        Just(-0.0),
        Just(5e-324),
        Just(1e-38),
        Just(3e38),
        Just(1e308),
        -1.0f64..2.0,
        any::<f64>(),
    ]
}

fn edit() -> impl Strategy<Value = Edit> {
    let typed = (
        hostile_int(),
        hostile_float(),
        prop_oneof![4 => experiment_word(), 1 => hostile_value()],
        prop::collection::vec(
            prop_oneof![8 => experiment_word(), 1 => hostile_value()],
            0..4,
        ),
    )
        .prop_map(|(i, f, v, w)| Edit::Typed(i, f, v, w));
    prop_oneof![
        20 => typed,
        2 => hostile_value().prop_map(Edit::Set),
        1 => (1usize..200).prop_map(|d| Edit::Set(deep(d))),
        2 => Just(Edit::Remove),
        1 => ("[a-z_]{1,10}", hostile_value()).prop_map(|(k, v)| Edit::Extra(k, v)),
        1 => hostile_value().prop_map(Edit::SectionTo),
    ]
}

/// Every path to a leaf (or an array of tables' first element) of `table`.
fn leaf_paths(table: &toml::Table, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    for (k, v) in table {
        prefix.push(k.clone());
        match v {
            Value::Table(t) if !t.is_empty() => leaf_paths(t, prefix, out),
            Value::Array(a) if matches!(a.first(), Some(Value::Table(_))) => {
                if let Some(Value::Table(t)) = a.first() {
                    prefix.push("0".into());
                    leaf_paths(t, prefix, out);
                    prefix.pop();
                }
            }
            _ => out.push(prefix.clone()),
        }
        prefix.pop();
    }
}

/// Applies `edit` at `path` of `doc`.
fn apply(doc: &mut Value, path: &[String], edit: &Edit) {
    let (last, parents) = path.split_last().expect("a path");
    let mut node = doc;
    for key in parents {
        let next = match node {
            Value::Table(t) => t.get_mut(key),
            Value::Array(a) => key.parse::<usize>().ok().and_then(|i| a.get_mut(i)),
            _ => None,
        };
        match next {
            Some(n) => node = n,
            None => return,
        }
    }
    if let (Value::Table(t), Edit::Typed(i, f, v, w)) = (&mut *node, edit) {
        if let Some(old) = t.get_mut(last) {
            *old = match old {
                Value::Integer(_) => Value::Integer(*i),
                Value::Float(_) => Value::Float(*f),
                Value::Boolean(b) => Value::Boolean(!*b),
                Value::Array(a) => match a.first() {
                    Some(Value::Integer(_)) => {
                        Value::Array(vec![Value::Integer(*i); w.len().max(1)])
                    }
                    Some(Value::Float(_)) => {
                        let mut a = a.clone();
                        let k = (*i).unsigned_abs() as usize % a.len();
                        a[k] = Value::Float(*f);
                        Value::Array(a)
                    }
                    _ => Value::Array(w.clone()),
                },
                _ => v.clone(),
            };
        }
        return;
    }
    match (node, edit) {
        (Value::Table(t), Edit::Set(v)) => {
            t.insert(last.clone(), v.clone());
        }
        (Value::Table(t), Edit::Remove) => {
            t.remove(last);
        }
        (Value::Table(t), Edit::Extra(k, v)) => {
            t.insert(format!("{k}_extra"), v.clone());
        }
        (Value::Table(t), Edit::SectionTo(v)) => {
            t.insert(last.clone(), v.clone());
        }
        (Value::Array(a), Edit::Set(v)) => {
            if let Some(slot) = last.parse::<usize>().ok().and_then(|i| a.get_mut(i)) {
                *slot = v.clone();
            }
        }
        _ => {}
    }
}

/// A valid document with a few edits applied, serialised; sometimes cut short or spliced
/// with bytes, the way a torn or corrupted file looks.
fn mutated(base: &'static str) -> impl Strategy<Value = String> {
    let doc: Value = Value::Table(base.parse::<toml::Table>().expect("valid base"));
    let mut paths = Vec::new();
    if let Value::Table(t) = &doc {
        leaf_paths(t, &mut Vec::new(), &mut paths);
    }
    let n = paths.len();
    let edits = prop::collection::vec((0..n, edit()), 1..3);
    let tail = prop_oneof![
        16 => Just(None),
        1 => (0.0f64..1.0).prop_map(|f| Some((f, String::new()))),
        1 => (0.0f64..1.0, "[\\[\\]={}\"'#a-z0-9 \n.,-]{0,24}").prop_map(|(f, s)| Some((f, s))),
    ];
    (edits, tail).prop_map(move |(edits, tail)| {
        let mut doc = doc.clone();
        for (i, e) in &edits {
            // A section replaced whole: the path's first component.
            let path = match e {
                Edit::SectionTo(_) => paths[*i][..1].to_vec(),
                _ => paths[*i].clone(),
            };
            apply(&mut doc, &path, e);
        }
        let mut text = toml::to_string(&doc).unwrap_or_default();
        if let Some((at, splice)) = tail {
            let mut cut = (text.len() as f64 * at) as usize;
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            text.truncate(cut);
            text.push_str(&splice);
        }
        text
    })
}

const CONFIG: &str = include_str!("../configs/hardware/vizard2.toml");
const TRANSFER: &str = include_str!("../configs/transfer/phantom-sphere-class.toml");
const PATH: &str = include_str!("../configs/paths/tube.toml");
const EXPERIMENT: &str = r#"
name = "prop"
description = "generated"
datasets = ["phantom:sphere:8", "phantom:shells:8"]
tf = ["zero", "class"]
modes = ["none", "ert+leap4", "ert+leap4+hier", "ert+bricks4+table", "ert+distance4"]
models = ["step", "cycle"]
raise_sram = false
zip = [["skip.latency", "compositing.stage_latency"]]
[frames]
orbit = 8
select = [0, 3]
size = "4x4"
projection = "ortho"
[axes]
"ray_queue.rays" = [8, 16]
"skip.latency" = [1, 2]
"compositing.stage_latency" = [3, 4]
[[exclude]]
dataset = "phantom:shells:8"
mode = "none"
[sequence]
steps = 2
dt = 0.05
brick = 4
map = ["update", "none"]
"#;

/// Values an experiment's lists take: dataset names and specs, modes, models, TFs, sizes.
fn experiment_word() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just("phantom:sphere:8"),
        Just("phantom:sphere:0"),
        Just("phantom:sphere:1"),
        Just("phantom:sphere:100000"),
        Just("phantom:metaballs:8"),
        Just("phantom:tsdf:8"),
        Just("phantom:sphere:8:seed=-1"),
        Just("phantom:nothing"),
        Just("nowhere"),
        Just("/dev/zero"),
        Just(""),
        Just("none"),
        Just("ert+leap8+hier"),
        Just("leap0"),
        Just("iso99"),
        Just("ert+iso2+leapvalues"),
        Just("bricks64"),
        Just("table"),
        Just("distance99"),
        Just("+"),
        Just("step"),
        Just("cycle"),
        Just("float"),
        Just("zero"),
        Just("class"),
        Just("0x0"),
        Just("65536x65536"),
        Just("4x4"),
        Just("scan"),
        Just("rescan"),
        Just("update"),
    ]
    .prop_map(|s| Value::String(s.to_string()))
}

/// Experiment edits also draw from the words experiments are made of.
fn experiment_text() -> impl Strategy<Value = String> {
    let words = || prop::collection::vec(experiment_word(), 0..4).prop_map(Value::Array);
    let fields = prop_oneof![
        Just("datasets"),
        Just("tf"),
        Just("modes"),
        Just("models"),
        Just("zip"),
        Just("exclude"),
    ];
    let frames = prop_oneof![
        Just("orbit"),
        Just("select"),
        Just("every"),
        Just("size"),
        Just("projection"),
        Just("path"),
    ];
    let axis = prop_oneof![
        Just("ray_queue.rays"),
        Just("skip.latency"),
        Just("occupancy.sram_bits"),
        Just("clock.step_time_ns"),
        Just("memory.timing.t_rcd"),
        Just("iso.value"),
        Just("no.such"),
        Just(""),
    ];
    let word_edit = prop_oneof![
        (fields, prop_oneof![4 => words(), 1 => hostile_value()]).prop_map(|(f, w)| (vec![f.to_string()], w)),
        (frames, prop_oneof![3 => experiment_word(), 3 => hostile_int().prop_map(Value::Integer), 1 => words(), 1 => hostile_value()])
            .prop_map(|(f, w)| (vec!["frames".to_string(), f.to_string()], w)),
        (axis, prop_oneof![hostile_value(), words()])
            .prop_map(|(a, w)| (vec!["axes".to_string(), a.to_string()], w)),
    ];
    (
        mutated(EXPERIMENT),
        prop::collection::vec(word_edit, 0..3),
        prop::bool::weighted(0.2),
    )
        .prop_map(|(text, edits, keep_sequence)| {
            let Ok(mut table) = text.parse::<toml::Table>() else {
                return text;
            };
            if !keep_sequence {
                table.remove("sequence");
            }
            let mut doc = Value::Table(table);
            for (path, value) in edits {
                let mut node = &mut doc;
                for key in &path[..path.len() - 1] {
                    let Value::Table(t) = node else { break };
                    node = t
                        .entry(key.clone())
                        .or_insert_with(|| Value::Table(toml::Table::new()));
                }
                if let Value::Table(t) = node {
                    t.insert(path[path.len() - 1].clone(), value);
                }
            }
            toml::to_string(&doc).unwrap_or_default()
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn hardware_configurations_never_panic_or_hang(text in mutated(CONFIG)) {
        bounded("a hardware configuration", move || {
            let _ = HardwareConfig::from_toml_str(&text, "generated.toml", &[]);
        });
    }

    #[test]
    fn set_overrides_never_panic_or_hang(
        field in "[a-z_]{1,12}(\\.[a-z_]{1,12}){0,3}",
        value in hostile_value(),
    ) {
        let assignment = format!("{field}={value}");
        bounded("an override", move || {
            let _ = HardwareConfig::from_toml_str(CONFIG, "vizard2.toml", &[assignment]);
        });
    }

    #[test]
    fn transfer_functions_never_panic_or_hang(text in mutated(TRANSFER)) {
        bounded("a transfer function", move || {
            if let Ok(tf) = TransferFunction::from_toml(&text, "generated.toml", "generated") {
                // A function that loads is usable: its table and lookups work.
                let table = tf.sample_table(256);
                assert_eq!(table.len(), 256);
                let _ = tf.eval(f32::NAN);
                let _ = tf.eval(1e9);
            }
        });
    }

    #[test]
    fn camera_paths_never_panic_or_hang(text in mutated(PATH), k in 0u32..200, n in 0u32..200) {
        bounded("a camera path", move || {
            if let Ok(path) = CameraPath::parse(&text, "generated.toml") {
                let _ = path.pose(k, n);
            }
        });
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn experiment_files_never_panic_or_hang(text in experiment_text()) {
        bounded("an experiment", move || {
            // The dry run's path (validation, then streaming) and the full expansion.
            if let Ok(plan) = spec::plan(&text, "generated.toml", None) {
                let mut n = 0;
                let _ = plan.for_each_run(|_| {
                    n += 1;
                    Ok(())
                });
            }
            let _ = spec::expand(&text, "generated.toml", None);
        });
    }
}

/// The documents the strategies mutate are valid, so that a mutation is one step from a
/// working input (the experiment without its `[sequence]`, which the strategy keeps only
/// sometimes).
#[test]
fn the_documents_mutated_are_valid() {
    assert!(HardwareConfig::from_toml_str(CONFIG, "vizard2.toml", &[]).is_ok());
    assert!(TransferFunction::from_toml(TRANSFER, "sphere.toml", "sphere").is_ok());
    assert!(CameraPath::parse(PATH, "tube.toml").is_ok());
    let mut table: toml::Table = EXPERIMENT.parse().unwrap();
    table.remove("sequence");
    let text = toml::to_string(&table).unwrap();
    let expansion = spec::expand(&text, "prop.toml", None).unwrap();
    assert!(!expansion.runs.is_empty());
}
