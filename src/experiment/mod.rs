//! Experiments at scale: expand an experiment file into runs (`spec`), run them in parallel
//! and keep every finished result (`store`), combine shards (`merge`).
//!
//! Results are deterministic JSON lines (no wall time, no thread count): the same run gives
//! the same line on any machine, so a resumed, sharded or merged sweep is comparable line by
//! line with an uninterrupted one. Wall times go to `timing.jsonl` beside the results.

pub mod spec;
pub mod store;

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;
use serde_json::{json, Value};

use crate::dynamic::{run_sequence, SequenceOptions, StepView};
use crate::error::{Error, Result};
use crate::run::{self, Measurements, Prepared, Probes};
use spec::{dataset_label, Expansion, Model, RunSpec};
use store::ResultStore;

/// `--shard I/N`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn parse(text: &str) -> Result<Shard> {
        let bad = || {
            Error::Invalid(format!(
                "--shard {text}: expected I/N with 0 <= I < N (e.g. 0/4)"
            ))
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    pub fn contains(&self, run: &RunSpec) -> bool {
        run.index % self.count == self.index
    }
}

/// Runs one frame of a prepared group through the one run path and returns its result line:
/// where the run sits in the experiment, then the run's measurements.
fn run_frame(run: &RunSpec, prepared: &Prepared, experiment: &str) -> Result<Value> {
    let measured = measure_frame(run, prepared)?;
    result_line(run, experiment, prepared, &measured)
}

/// The run's measurements (the result line's fields after its identity).
fn measure_frame(run: &RunSpec, prepared: &Prepared) -> Result<Measurements> {
    Ok(run::execute(&run.run, prepared, Probes::default())?.measurements)
}

/// A result line: the run's identity, then its measurements.
fn result_line(
    run: &RunSpec,
    experiment: &str,
    prepared: &Prepared,
    measured: &Measurements,
) -> Result<Value> {
    match serde_json::to_value(measured) {
        Ok(Value::Object(measured)) => Ok(line_of(run, experiment, prepared, measured)),
        Ok(_) => Ok(identity_line(run, experiment, &prepared.transfer_function)),
        Err(e) => Err(Error::Invalid(format!("result of run {}: {e}", run.key))),
    }
}

/// The run's identity, then the measurement fields `measured`.
fn line_of(
    run: &RunSpec,
    experiment: &str,
    prepared: &Prepared,
    measured: serde_json::Map<String, Value>,
) -> Value {
    let mut line = identity_line(run, experiment, &prepared.transfer_function);
    line.as_object_mut().expect("object").extend(measured);
    line
}

/// Where a run sits in the experiment: the first fields of its result line.
fn identity_line(run: &RunSpec, experiment: &str, transfer_function: &str) -> Value {
    let desc = &run.run;
    let (label, stand_in) = dataset_label(&desc.dataset);
    let mut line = json!({
        "key": run.key,
        "experiment": experiment,
        "dataset": desc.dataset,
        "dataset_label": label,
        "stand_in": stand_in,
        "tf": desc.tf,
        "transfer_function": transfer_function,
        "mode": run.mode.name(),
        "model": desc.model,
        "frame": run.frame,
        "view": desc.view,
        "width": desc.size.0,
        "height": desc.size.1,
        "axes": run.axes,
        "ert": run.mode.ert,
        "subcube": run.mode.subcube,
        "hierarchy": run.mode.hierarchy,
        "fits_default_sram": run.fits_default_sram,
        "sram_bits": desc.hardware.occupancy.sram_bits,
    });
    if let Some(step) = &run.sequence {
        let obj = line.as_object_mut().expect("object");
        obj.insert("time_step".into(), json!(step.time_step));
        obj.insert("map".into(), json!(step.map.name()));
        obj.insert("dt".into(), json!(step.dt));
        obj.insert("brick".into(), json!(step.brick));
    }
    line
}

/// The result line of one time step of a sequence: the run's identity, the frame's
/// measurements (`cycles` are the render cycles), then the step's update, map, render and total
/// cycles; `frame_time_ns` and `fps` are the whole step's (update + map + render).
fn step_line(run: &RunSpec, view: &StepView, experiment: &str, clock_mhz: f64) -> Result<Value> {
    let mut line = identity_line(run, experiment, view.transfer_function);
    let obj = line.as_object_mut().expect("object");
    if let Value::Object(measured) = serde_json::to_value(view.measurements)
        .map_err(|e| Error::Invalid(format!("result of run {}: {e}", run.key)))?
    {
        obj.extend(measured);
    }
    let s = view.report;
    let total_ns = s.total_cycles as f64 * 1e3 / clock_mhz;
    for (field, value) in [
        ("volume", json!(s.volume)),
        ("regions", json!(s.regions)),
        ("voxels_written", json!(s.voxels_written)),
        ("voxels_touched", json!(s.voxels_touched)),
        ("update_cycles", json!(s.update_cycles)),
        ("map_cycles", json!(s.map_cycles)),
        ("render_cycles", json!(s.render_cycles)),
        ("total_cycles", json!(s.total_cycles)),
        ("stale_subcubes", json!(s.stale_subcubes)),
        ("frame_time_ns", json!(total_ns)),
    ] {
        obj.insert(field.into(), value);
    }
    // Only where the map mode keeps the tables: the other lines stay as they were.
    if let Some(bits) = view.table_on_chip_bits {
        obj.insert("table_on_chip_bits".into(), json!(bits));
    }
    match crate::run::fps_of(total_ns) {
        Some(fps) => obj.insert("fps".into(), json!(fps)),
        None => obj.remove("fps"),
    };
    Ok(line)
}

/// Measurements of cycle runs by their timing description (`run::reuse_description`): a run
/// whose description equals a finished run's (the same run with another transfer function
/// where nothing reads it, with a leaping structure that never leaps, or, exact and reading no
/// voxel value, on another dataset of the same geometry) takes its measurements instead of
/// simulating. Its result line is the one simulating would write: the identity fields and the
/// map's own `skippable_subcubes_percent` are the run's, the rest is equal by construction
/// (`tests/sweep.rs` compares sweeps that reuse with sweeps that cannot). Kept as the line's
/// measurement fields, for every cycle run the sweep simulates (about 2 KB each:
/// `spec::BYTES_PER_RUN`) and, when a sweep resumes, for the cycle runs the folder holds.
#[derive(Default)]
struct TimingReuse {
    measured: Mutex<BTreeMap<String, serde_json::Map<String, Value>>>,
    reused: std::sync::atomic::AtomicUsize,
}

impl TimingReuse {
    /// The run's timing description as a key, for the cycle model (exact or sampled).
    fn timing_key(run: &RunSpec, prepared: &Prepared) -> Option<String> {
        if run.run.model != Model::Cycle {
            return None;
        }
        serde_json::to_string(&run::reuse_description(&run.run, prepared)).ok()
    }

    fn measured(
        &self,
    ) -> Result<std::sync::MutexGuard<'_, BTreeMap<String, serde_json::Map<String, Value>>>> {
        self.measured
            .lock()
            .map_err(|_| Error::Invalid("timing cache poisoned".into()))
    }

    /// Keeps the measurements of `line`, the result line a finished run wrote (a resumed
    /// sweep's earlier results): its fields but the identity.
    fn learn(
        &self,
        run: &RunSpec,
        prepared: &Prepared,
        experiment: &str,
        line: &Value,
    ) -> Result<()> {
        let (Some(timing_key), Some(fields)) = (Self::timing_key(run, prepared), line.as_object())
        else {
            return Ok(());
        };
        let identity = identity_line(run, experiment, &prepared.transfer_function);
        let identity = identity.as_object().expect("object");
        let measured = fields
            .iter()
            .filter(|(field, _)| !identity.contains_key(*field))
            .map(|(field, value)| (field.clone(), value.clone()))
            .collect();
        self.measured()?.entry(timing_key).or_insert(measured);
        Ok(())
    }

    /// Runs the frame, or builds its line from the measurements of a finished run with the
    /// same timing key.
    fn run_frame(&self, run: &RunSpec, prepared: &Prepared, experiment: &str) -> Result<Value> {
        let Some(timing_key) = Self::timing_key(run, prepared) else {
            return run_frame(run, prepared, experiment);
        };
        let known = self.measured()?.get(&timing_key).cloned();
        let measured = match known {
            Some(mut measured) => {
                self.reused
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                // The measurements of the structure itself, not of the frame: a twin may have
                // another map (one that never leaps) or none.
                match run::skippable_subcubes_percent(prepared) {
                    Some(percent) => {
                        measured.insert("skippable_subcubes_percent".into(), json!(percent))
                    }
                    None => measured.remove("skippable_subcubes_percent"),
                };
                match run::StructureMemory::of(&run.run, prepared.volume().dims) {
                    Some(memory) => measured.insert("structure_memory".into(), json!(memory)),
                    None => measured.remove("structure_memory"),
                };
                measured
            }
            None => {
                let measured = match serde_json::to_value(measure_frame(run, prepared)?) {
                    Ok(Value::Object(measured)) => measured,
                    Ok(_) => serde_json::Map::new(),
                    Err(e) => {
                        return Err(Error::Invalid(format!("result of run {}: {e}", run.key)))
                    }
                };
                self.measured()?.insert(timing_key, measured.clone());
                measured
            }
        };
        Ok(line_of(run, experiment, prepared, measured))
    }
}

/// With the experiment's `float_reference`, the line with the run's own image against the float
/// reference (after the measurements, which a twin may have taken from another run: its image
/// is its own). `reference` is the group's float reference, prepared once.
fn with_float_reference(
    mut line: Value,
    run: &RunSpec,
    prepared: &Prepared,
    reference: Option<&Prepared>,
) -> Result<Value> {
    if let (true, Some(reference)) = (run.float_reference, reference) {
        let comparison = run::compare_with_reference(&run.run, prepared, reference)?;
        line.as_object_mut()
            .expect("object")
            .insert("float_reference".into(), json!(comparison));
    }
    Ok(line)
}

/// Appends a finished run's line (and its wall time) to the shared store.
fn append(store: &Mutex<ResultStore>, key: &str, line: &Value, wall_seconds: f64) -> Result<()> {
    store
        .lock()
        .map_err(|_| Error::Invalid("results writer poisoned".into()))?
        .append(key, line, wall_seconds)
}

/// A run of the sweep as errors name it: its key, then where it sits in the experiment
/// (dataset, tf, mode, model, frame, image size, axis values: `store::describe_line`).
fn describe_run(run: &RunSpec, experiment: &str) -> String {
    let mut line = identity_line(run, experiment, "");
    if let (Some(sample), Some(obj)) = (&run.run.sample, line.as_object_mut()) {
        obj.insert("sample_rate".into(), json!(sample.rate));
    }
    format!("run {} ({})", run.key, store::describe_line(&line))
}

/// An error of one run of the sweep (preparing or executing it), naming the experiment file
/// and the run; `also` says which other runs it stops (those that share its preparation).
fn run_error(expansion: &Expansion, run: &RunSpec, also: &str, error: Error) -> Error {
    Error::Invalid(format!(
        "{}: {}{also}: {error}",
        expansion.source,
        describe_run(run, &expansion.experiment.name)
    ))
}

/// The error a sweep stops with: what went wrong, then what the folder keeps (every result
/// written, the failed run's included, stays in `results.jsonl`) and the command that goes on
/// (with the sweep's own `--shard` and `--model`: without them it would run other runs too).
fn stopped(
    error: Error,
    store: &Mutex<ResultStore>,
    expansion: &Expansion,
    out: &Path,
    (shard, model): (Option<Shard>, Option<Model>),
) -> Error {
    let kept = store.lock().map(|s| s.len()).unwrap_or_default();
    let mut again = format!(
        "vizsim sweep {} --out {}",
        crate::output::shell_word(&expansion.source),
        crate::output::shell_word(&out.display().to_string())
    );
    if let Some(s) = shard {
        again += &format!(" --shard {}/{}", s.index, s.count);
    }
    if let Some(m) = model {
        again += &format!(" --model {}", m.name());
    }
    Error::Invalid(format!(
        "{error}\nthe sweep stopped there; {} keeps the {kept} result{} written so far: fix \
         the run (or leave it out with [[exclude]], docs/experiments.md) and sweep again into \
         the same folder to run the rest: {again} (with this sweep's --data-dir and \
         --memory-budget, if it had them)",
        out.join(store::RESULTS).display(),
        if kept == 1 { "" } else { "s" },
    ))
}

/// Runs the pending time steps of sequence experiments: each sequence (source, TF,
/// configuration, view, map strategy) runs its frame loop from step 0 (a step depends on the
/// memory the previous steps left), up to its last pending step, and appends the line of
/// every pending step as the loop reaches it; steps already in the results are recomputed
/// (the loop needs them) but not written again.
fn sweep_sequences(
    expansion: &Expansion,
    pending: &[&RunSpec],
    store: &Mutex<ResultStore>,
    bar: &indicatif::ProgressBar,
) -> Result<()> {
    let name = &expansion.experiment.name;
    let mut groups: BTreeMap<String, Vec<&RunSpec>> = BTreeMap::new();
    let mut order = Vec::new();
    for run in pending {
        let g = run.sequence_group().expect("a sequence run");
        if !groups.contains_key(&g) {
            order.push(g.clone());
        }
        groups.entry(g).or_default().push(run);
    }
    // The longest sequences first.
    let last_step = |g: &String| -> usize {
        groups[g]
            .iter()
            .filter_map(|r| r.sequence.as_ref().map(|s| s.time_step))
            .max()
            .unwrap_or(0)
    };
    order.sort_by_key(|g| std::cmp::Reverse(last_step(g)));
    order.par_iter().try_for_each(|g| -> Result<()> {
        let runs = &groups[g];
        let first = runs[0];
        let step = first.sequence.as_ref().expect("a sequence run");
        let by_step: BTreeMap<usize, &RunSpec> = runs
            .iter()
            .map(|r| (r.sequence.as_ref().expect("a sequence run").time_step, *r))
            .collect();
        let options = SequenceOptions {
            steps: last_step(g) + 1,
            dt: step.dt as f32,
            brick: step.brick,
            map: step.map,
            verify: false,
        };
        let clock = first.run.hardware.clock.frequency_mhz;
        let mut t = Instant::now();
        // Writing a step's line is no error of the run: kept apart from the sequence's own.
        let mut written: Result<()> = Ok(());
        let outcome = run_sequence(&first.run, &step.source, &options, |view| {
            if let Some(run) = by_step.get(&view.report.step) {
                written = step_line(run, view, name, clock)
                    .and_then(|line| append(store, &run.key, &line, t.elapsed().as_secs_f64()));
                written
                    .as_ref()
                    .map_err(|e| Error::Invalid(e.to_string()))?;
                bar.inc(1);
            }
            t = Instant::now();
            Ok(())
        });
        written?;
        outcome.map_err(|e| {
            run_error(
                expansion,
                first,
                &format!(
                    "; its sequence ({} pending time step{}) stopped",
                    runs.len(),
                    if runs.len() == 1 { "" } else { "s" }
                ),
                e,
            )
        })?;
        Ok(())
    })
}

/// What a sweep did.
#[derive(Debug, Default)]
pub struct SweepSummary {
    pub total: usize,
    pub already_done: usize,
    pub ran: usize,
    pub torn_lines_dropped: usize,
    /// Cycle runs that took the measurements of a run with the same timing description
    /// (`run::reuse_description`) instead of simulating.
    pub timings_reused: usize,
    pub wall_seconds: f64,
}

/// Runs the pending runs of `expansion` (those in `shard` and of `model`, not yet in `out`),
/// appending each result line to `out/results.jsonl` as it finishes. The folder's description
/// lists every run of the expansion with the shard and model swept, so that folders swept with
/// different `--model`s are recognised as one version of the experiment (`merge`).
pub fn sweep(
    expansion: &Expansion,
    out: &Path,
    shard: Option<Shard>,
    model: Option<Model>,
    progress: bool,
) -> Result<SweepSummary> {
    let lock = store::lock_folder(out)?;
    sweep_locked(expansion, out, lock, shard, model, progress)
}

/// `sweep` into a folder whose lock the caller took (`store::lock_folder`), e.g. before
/// printing a plan, so that no other sweep can take the folder in between.
pub fn sweep_locked(
    expansion: &Expansion,
    out: &Path,
    lock: std::fs::File,
    shard: Option<Shard>,
    model: Option<Model>,
    progress: bool,
) -> Result<SweepSummary> {
    let start = Instant::now();
    ResultStore::check_same_experiment(out, &expansion.experiment.name)?;
    let mine: Vec<&RunSpec> = expansion
        .runs
        .iter()
        .filter(|r| shard.is_none_or(|s| s.contains(r)) && model.is_none_or(|m| r.run.model == m))
        .collect();
    let store = ResultStore::open_locked(out, lock)?;
    store.write_resolved(expansion, shard, model)?;
    let pending: Vec<&RunSpec> = mine
        .iter()
        .copied()
        .filter(|r| !store.has(&r.key))
        .collect();
    let mut summary = SweepSummary {
        total: mine.len(),
        already_done: mine.len() - pending.len(),
        torn_lines_dropped: store.torn_lines_dropped,
        ..Default::default()
    };
    let bar = if progress {
        let bar = indicatif::ProgressBar::new(pending.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} runs  {per_sec}  elapsed {elapsed_precise}  left {eta_precise}",
            )
            .expect("valid template"),
        );
        bar
    } else {
        indicatif::ProgressBar::hidden()
    };
    // Group by everything but the frame: one renderer per group, frames in parallel.
    let mut groups: BTreeMap<(String, String, String), Vec<&RunSpec>> = BTreeMap::new();
    let mut order = Vec::new();
    for run in &pending {
        let g = run.group();
        if !groups.contains_key(&g) {
            order.push(g.clone());
        }
        groups.entry(g).or_default().push(run);
    }
    // Groups run in parallel too (a group may have fewer frames than there are cores), the
    // longest first so that no long group is left running alone at the end.
    let cost = |g: &(String, String, String)| -> f64 {
        groups[g]
            .iter()
            .map(|run| estimated_run_seconds(expansion, run))
            .sum()
    };
    order.sort_by(|a, b| cost(b).total_cmp(&cost(a)));
    // A resumed sweep: the cycle runs the folder holds are timings to reuse as well.
    let finished: Vec<&RunSpec> = if pending.iter().any(|r| r.run.model == Model::Cycle) {
        expansion
            .runs
            .iter()
            .filter(|r| r.run.model == Model::Cycle && store.has(&r.key))
            .collect()
    } else {
        Vec::new()
    };
    let store = Mutex::new(store);
    let name = &expansion.experiment.name;
    if expansion.experiment.sequence.is_some() {
        sweep_sequences(expansion, &pending, &store, &bar)
            .map_err(|e| stopped(e, &store, expansion, out, (shard, model)))?;
        bar.finish_and_clear();
        summary.ran = pending.len();
        summary.wall_seconds = start.elapsed().as_secs_f64();
        return Ok(summary);
    }
    let reuse = TimingReuse::default();
    learn_finished(expansion, out, &finished, &reuse)?;
    order
        .par_iter()
        .try_for_each(|g| -> Result<()> {
            let runs = &groups[g];
            let volume = &expansion.volumes[&runs[0].run.dataset];
            // Preparing fails for every frame of the group alike: named by its first.
            let prepared = run::prepare(&runs[0].run, volume).map_err(|e| {
                let others = runs.len() - 1;
                let also = match others {
                    0 => String::new(),
                    n => format!(
                        " and the {n} other frame{} prepared with it",
                        if n == 1 { "" } else { "s" }
                    ),
                };
                run_error(expansion, runs[0], &also, e)
            })?;
            // The float reference of the group, with the experiment's `float_reference`.
            let reference = match runs[0].float_reference {
                true => Some(
                    run::prepare(&run::reference_run(&runs[0].run), volume)
                        .map_err(|e| run_error(expansion, runs[0], "", e))?,
                ),
                false => None,
            };
            runs.par_iter().try_for_each(|run| -> Result<()> {
                let t = Instant::now();
                let line = reuse
                    .run_frame(run, &prepared, name)
                    .and_then(|line| with_float_reference(line, run, &prepared, reference.as_ref()))
                    .map_err(|e| run_error(expansion, run, "", e))?;
                append(&store, &run.key, &line, t.elapsed().as_secs_f64())?;
                bar.inc(1);
                Ok(())
            })
        })
        .map_err(|e| stopped(e, &store, expansion, out, (shard, model)))?;
    bar.finish_and_clear();
    summary.ran = pending.len();
    summary.timings_reused = reuse.reused.into_inner();
    summary.wall_seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// Keeps the measurements of `finished`, cycle runs whose lines `out` holds, for reuse by their
/// twins. Each run's group is prepared to learn its timing description; a group that cannot be
/// prepared now is left out (its twins simulate).
fn learn_finished(
    expansion: &Expansion,
    out: &Path,
    finished: &[&RunSpec],
    reuse: &TimingReuse,
) -> Result<()> {
    if finished.is_empty() {
        return Ok(());
    }
    // Only results this model measured: a line of an older vizsim (a folder resumed after an
    // upgrade) keeps its own run but spreads to no twin.
    let measured_here: std::collections::HashSet<String> =
        store::read_timing(&out.join(store::TIMING))?
            .into_iter()
            .filter(|(time, _)| time.get("model").and_then(Value::as_str) == Some(store::MODEL))
            .filter_map(|(time, _)| Some(time.get("key")?.as_str()?.to_string()))
            .collect();
    let keys: std::collections::HashSet<&str> = finished
        .iter()
        .map(|r| r.key.as_str())
        .filter(|key| measured_here.contains(*key))
        .collect();
    let lines: BTreeMap<String, Value> = store::read_lines(&out.join(store::RESULTS))?
        .into_iter()
        .filter_map(|(line, _)| {
            let key = line.get("key")?.as_str()?.to_string();
            keys.contains(key.as_str()).then_some((key, line))
        })
        .collect();
    let mut groups: BTreeMap<(String, String, String), Vec<&RunSpec>> = BTreeMap::new();
    for run in finished {
        groups.entry(run.group()).or_default().push(run);
    }
    let name = &expansion.experiment.name;
    groups.par_iter().try_for_each(|(_, runs)| -> Result<()> {
        let volume = &expansion.volumes[&runs[0].run.dataset];
        let Ok(prepared) = run::prepare(&runs[0].run, volume) else {
            return Ok(());
        };
        for run in runs {
            if let Some(line) = lines.get(&run.key) {
                reuse.learn(run, &prepared, name, line)?;
            }
        }
        Ok(())
    })
}

/// A rough time estimate for a dry run, in seconds on `threads` cores. Steps per frame ≈
/// pixels × the volume's largest extent × a mode factor (0.8 none, 0.75 ERT, 0.4 leaping: the
/// paper protocol's measured means). Rates per core as measured in a sweep on the 2-core
/// machine (docs/results.md): step model 50 M steps/s, cycle model 5 M cycles/s at 1.1 cycles
/// per step. A sampled cycle run costs the functional frame plus the cycle model on the share
/// of the rays it simulates (`Sampling::simulated_share`); for the protocol at rate 0.05 this
/// gives 0.2 of the exact cost, as measured (1,611 CPU-seconds against about 8,400).
pub fn estimate_seconds(expansion: &Expansion, runs: &[&RunSpec], threads: usize) -> f64 {
    // A fold from +0.0: an empty float sum is -0.0 and would print as "-0".
    let total = runs
        .iter()
        .map(|run| estimated_run_seconds(expansion, run))
        .fold(0.0, |a, b| a + b);
    total / threads.max(1) as f64
}

/// One run's estimated time on one core, in seconds (see `estimate_seconds`).
fn estimated_run_seconds(expansion: &Expansion, run: &RunSpec) -> f64 {
    run_seconds(&expansion.volumes, run)
}

/// One run's estimated time on one core, in seconds, from the experiment's volumes (the dry
/// run sums these as it streams the runs).
pub fn run_seconds(
    volumes: &BTreeMap<String, std::sync::Arc<crate::volume::Volume>>,
    run: &RunSpec,
) -> f64 {
    let desc = &run.run;
    let dims = volumes[&desc.dataset].dims;
    let largest = *dims.iter().max().unwrap_or(&1) as f64;
    let factor = if run.mode.subcube > 0 {
        0.4
    } else if run.mode.ert {
        0.75
    } else {
        0.8
    };
    let mut steps = desc.size.0 as f64 * desc.size.1 as f64 * largest * factor;
    if run.sequence.is_some() {
        // A time step also runs the update engine: about a cycle per five voxels changed.
        steps += dims.iter().product::<usize>() as f64 * 0.2;
    }
    let cycle_model = steps * 1.1 / 5e6;
    // With `float_reference`: a float frame (every sample) and the fixed-point frame more.
    let reference = match run.float_reference {
        true => (desc.size.0 as f64 * desc.size.1 as f64 * largest * 0.8 + steps) / 50e6,
        false => 0.0,
    };
    reference
        + match (desc.model, &desc.sample) {
            (Model::Float | Model::Step, _) => steps / 50e6,
            (Model::Cycle, None) => cycle_model,
            (Model::Cycle, Some(_)) => {
                let sampling = desc.sampling().expect("a sampled run");
                let rays = desc.size.0 as usize * desc.size.1 as usize;
                steps / 50e6 + cycle_model * sampling.simulated_share(rays)
            }
        }
}

/// Merges the results of several sweep folders (shards) into `out`: duplicates by key must
/// agree; the merged file is sorted by key, so any split of the same runs merges to the same
/// bytes. Wall times (`timing.jsonl`) are merged too, one per run, the first input's when a
/// run was timed in several (wall times differ between machines; results do not).
pub fn merge(inputs: &[&Path], out: &Path) -> Result<Merged> {
    let mut lines: BTreeMap<String, String> = BTreeMap::new();
    // Where each run was first read, to name both inputs when another differs.
    let mut first_from: BTreeMap<String, String> = BTreeMap::new();
    // A misspelt shard folder must not merge as "no results".
    if let Some(dir) = inputs.iter().find(|d| !d.is_dir()) {
        return Err(Error::Invalid(format!(
            "{}: {}",
            dir.display(),
            if dir.exists() {
                "is a file, not a sweep folder"
            } else {
                "no such sweep folder"
            }
        )));
    }
    // A folder without results is no sweep folder (a sweep makes the file when it starts).
    if let Some(dir) = inputs.iter().find(|d| !d.join(store::RESULTS).exists()) {
        return Err(Error::Invalid(format!(
            "{}: no {} here: not a sweep folder",
            dir.display(),
            store::RESULTS
        )));
    }
    store::must_be_a_folder(out)?;
    // The merged file replaces the output folder's results, so results already there are merged
    // in as if the folder were one more input: a merge never drops a result (re-merging shards
    // that have run further keeps working; a result that differs is the usual error).
    let same_folder = |dir: &Path| match (dir.canonicalize(), out.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    // No sweep (or other merge) may write into the output folder meanwhile: its lines would go
    // to the file this merge replaces. An existing folder is locked before its results are
    // read; a new one is made (and locked) only once every input has been read, and must then
    // still hold no results.
    let mut lock = if out.is_dir() {
        Some(store::lock_folder(out)?)
    } else {
        None
    };
    let mut inputs = inputs.to_vec();
    let out_merged_in = out.join(store::RESULTS).exists() && !inputs.iter().any(|d| same_folder(d));
    if out_merged_in {
        inputs.push(out);
    }
    let described = |dir: &Path| -> String {
        if out_merged_in && dir == out {
            format!("{} (the --out folder's earlier results)", dir.display())
        } else {
            dir.display().to_string()
        }
    };
    // Results of one experiment only (by the name in the result lines and in each folder's
    // description): a folder of another would mix configurations.
    let mut experiment: Option<(String, String)> = None;
    let mut same_experiment = |name: &str, dir: &Path| -> Result<()> {
        match &experiment {
            None => experiment = Some((name.to_string(), described(dir))),
            Some((first, at)) if first != name => {
                return Err(Error::Invalid(format!(
                    "{} holds experiment `{name}`, but {at} holds experiment `{first}`: merge \
                     the shards of one experiment",
                    described(dir)
                )))
            }
            _ => {}
        }
        Ok(())
    };
    // And of one version of it: shards swept from different experiment files (an axis value
    // changed between them) would merge into a folder whose description names only the first.
    let mut version: Option<(Value, String)> = None;
    // The `--model` each input was swept with ("null": both).
    let mut models_swept = std::collections::BTreeSet::new();
    let mut torn = Vec::new();
    for dir in &inputs {
        if let Some(name) = store::experiment_name(dir)? {
            same_experiment(&name, dir)?;
        }
        // The runs the version expands to (their keys), not the file's text: a description
        // edited between shards changes no run.
        let resolved = crate::input::read_existing(&dir.join(store::RESOLVED))?
            .and_then(|bytes| serde_json::from_slice::<Value>(&bytes).ok());
        if let Some(resolved) = &resolved {
            models_swept.insert(
                resolved
                    .get("model")
                    .cloned()
                    .unwrap_or(Value::Null)
                    .to_string(),
            );
        }
        let file = resolved.and_then(|resolved| {
            let keys: std::collections::BTreeSet<String> = resolved
                .get("runs")?
                .as_array()?
                .iter()
                .filter_map(|r| r.get("key")?.as_str().map(str::to_string))
                .collect();
            Some(Value::from(keys.into_iter().collect::<Vec<_>>()))
        });
        if let Some(file) = file {
            match &version {
                None => version = Some((file, described(dir))),
                Some((first, at)) if *first != file => {
                    return Err(Error::Invalid(format!(
                        "{} and {at} were swept from different versions of experiment `{}` \
                         (its runs changed between them); merge the shards of one version",
                        described(dir),
                        experiment
                            .as_ref()
                            .map(|(n, _)| n.as_str())
                            .unwrap_or_default()
                    )))
                }
                _ => {}
            }
        }
        let path = dir.join(store::RESULTS);
        let (read, torn_here) = store::read_lines_and_torn(&path)?;
        if torn_here {
            torn.push(path.clone());
        }
        for (line, text) in read {
            let key = line
                .get("key")
                .and_then(Value::as_str)
                .ok_or_else(|| Error::format(&path, "a result line without a key"))?
                .to_string();
            let name = line.get("experiment").and_then(Value::as_str).unwrap_or("");
            same_experiment(name, dir)?;
            match lines.get(&key) {
                Some(seen) if *seen != text => {
                    return Err(Error::format(
                        &path,
                        format!(
                            "run {key} differs from the same run in {}{}",
                            first_from
                                .get(&key)
                                .map_or("another input".to_string(), |at| at.clone()),
                            if out_merged_in && *dir == out {
                                " (this is the --out folder's earlier result: merge into \
                                 another folder to replace it)"
                            } else {
                                ""
                            }
                        ),
                    ));
                }
                Some(_) => {}
                None => {
                    first_from.insert(key.clone(), described(dir));
                    lines.insert(key, text);
                }
            }
        }
    }
    // Everything is read before anything is written: an unreadable input leaves no output.
    let mut timings: BTreeMap<String, String> = BTreeMap::new();
    for dir in &inputs {
        for (line, text) in store::read_timing(&dir.join(store::TIMING))? {
            let key = line.get("key").and_then(Value::as_str);
            if let Some(key) = key.filter(|k| lines.contains_key(*k)) {
                timings.entry(key.to_string()).or_insert(text);
            }
        }
    }
    // Read before anything is written (the first input may be the output folder itself; the
    // rewrite is atomic).
    let resolved = match inputs.first() {
        Some(first) => crate::input::read_existing(&first.join(store::RESOLVED))?,
        None => None,
    };
    if lock.is_none() {
        lock = Some(store::lock_folder(out)?);
        if out.join(store::RESULTS).exists() {
            return Err(Error::Invalid(format!(
                "{}: results appeared in the folder while merging (a sweep into it?); run the \
                 merge again",
                out.display()
            )));
        }
    }
    // Each file is written atomically, all or none (a folder in the way of one leaves none),
    // and results.jsonl placed last: a merge killed half-way leaves the previous results (or
    // none), never results without their timings.
    crate::output::all_or_none(|| -> Result<()> {
        if !timings.is_empty() {
            write_lines(&out.join(store::TIMING), &timings)?;
        }
        if let Some(text) = resolved {
            match serde_json::from_slice::<Value>(&text) {
                // The merged folder is no shard: the first input's description, shard null as
                // an unsharded sweep writes it.
                Ok(Value::Object(mut description)) if description.contains_key("shard") => {
                    description.insert("shard".into(), Value::Null);
                    // Inputs swept with different `--model`s merge into a folder of both.
                    if models_swept.len() > 1 {
                        description.insert("model".into(), Value::Null);
                    }
                    crate::output::write_json(&out.join(store::RESOLVED), &description)?;
                }
                _ => crate::output::write_atomically(&out.join(store::RESOLVED), |w| {
                    use std::io::Write;
                    w.write_all(&text)
                })?,
            }
        }
        write_lines(&out.join(store::RESULTS), &lines)
    })?;
    drop(lock);
    Ok(Merged {
        runs: lines.len(),
        torn,
    })
}

/// What `merge` wrote.
#[derive(Debug)]
pub struct Merged {
    /// Runs in the merged results.
    pub runs: usize,
    /// Inputs' results files whose torn last line (a shard killed mid-line) was left out: the
    /// run it held is not merged, and running that shard again redoes it.
    pub torn: Vec<std::path::PathBuf>,
}

/// Writes JSON lines (the map's values, in key order) atomically.
fn write_lines(path: &Path, lines: &BTreeMap<String, String>) -> Result<()> {
    crate::output::write_atomically(path, |w| {
        use std::io::Write;
        for text in lines.values() {
            w.write_all(text.as_bytes())?;
            w.write_all(b"\n")?;
        }
        Ok(())
    })
}
