//! The cycle-accurate pipeline: wires the units and runs the clock.
//!
//! ```text
//! ray setup -> ray queue -(issue)-> skip unit (latency L) -> back to the ray queue
//!                  |  sample                                      ^ ERT feedback (delayed)
//!                  v                                              |
//!            voxel memory -> compositing buffer (reorder) -> stages (interpolate, classify,
//!                                                             shade, composite) -> retire
//! ```
//!
//! **Clocking.** Each cycle the units are stepped back to front (retire first, ray setup last),
//! so a value a unit produces in cycle t is consumed by its downstream unit in cycle t + 1: the
//! order of the step calls cannot change the outcome. **Dead time.** When a cycle makes no
//! progress anywhere, nothing can change until the next timed event (a skip result, a memory
//! completion, a stage output, an ERT feedback), so the clock jumps there, adding the skipped
//! cycles to the same stall cause; `tests/cycle.rs` checks this equals ticking.
//!
//! **Arithmetic is not written twice**: ray setup, the skip decision, interpolation,
//! classification, shading and compositing are the functional model's own functions (through
//! `FixedRenderer`), so the image equals the functional image bit for bit by construction.

use std::collections::VecDeque;

use super::command_trace::{CommandTrace, IssuedCommand};
use super::compositing_buffer::CompositingBuffer;
use super::ray_queue::{RayQueue, RaySlot};
use super::skip_unit::{PositionUpdate, SkipUnit};
use super::trace::{Probe, Waveform};
use super::voxel_memory::{SampleRequest, VoxelMemory, WORD_TAG};
use crate::bricks::{setup_cycles, table_cost, RayRangeStats};
use crate::camera::Camera;
use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::functional::arith::Accumulator;
use crate::functional::leaping::{SampleValue, SkipState, SpaceSkipper};
use crate::functional::renderer::FixedRenderer;
use crate::render::{Frame, RayRecord};

/// Why the ray queue issued nothing in a cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct StallCycles {
    /// No ray in the queue (setup has not delivered, or the frame is draining).
    pub ray_queue_empty: u64,
    /// Every ray in the queue is waiting for its update from the skip unit.
    pub skip_unit_busy: u64,
    /// The selected sample's address FIFOs were full.
    pub memory: u64,
    /// The compositing buffer had no free entry.
    pub compositing_buffer_full: u64,
    /// Every ray in the queue is busy and at least one waits for its distance word from
    /// memory (distance-volume leaping only; not written out when 0).
    #[serde(skip_serializing_if = "is_zero")]
    pub distance_word: u64,
    /// Every ray in the queue is busy and at least one waits for its last sample's words to
    /// learn how far it goes (leap values in the volume, and an iso-surface's hit and
    /// refinement samples; not written out when 0).
    #[serde(skip_serializing_if = "is_zero")]
    pub leap_word: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct CycleStats {
    /// Cycles from the first ray setup to the last pixel written.
    pub cycles: u64,
    /// Issue slots used: samples + leaps (one per cycle at most).
    pub steps: u64,
    /// Samples issued (memory requests), leap samples included.
    pub samples: u64,
    /// Steps that issued no sample (leap-only leaps).
    pub leaps: u64,
    /// Samples followed by a leap (`skip.policy = "sample-then-leap"`); included in `samples`.
    pub leap_samples: u64,
    /// Iso mode: refinement samples (included in `samples`; not written out when 0).
    #[serde(skip_serializing_if = "is_zero")]
    pub refinement_samples: u64,
    /// One-word reads of the distance volume (one per position a ray reaches; distance-volume
    /// leaping only; not written out when 0).
    #[serde(skip_serializing_if = "is_zero")]
    pub distance_reads: u64,
    /// Samples composited (in ray order).
    pub composited: u64,
    /// Samples issued after their ray reached the ERT threshold, discarded at compositing.
    pub discarded_after_ert: u64,
    pub rays: u64,
    pub rays_terminated_early: u64,
    pub stall_cycles: StallCycles,
    /// Cycles spent at each ray-queue occupancy 0..=R.
    pub ray_queue_occupancy: Vec<u64>,
    /// Cycles spent at each compositing-buffer fill level 0..=capacity.
    pub compositing_buffer_occupancy: Vec<u64>,
    /// Cycles the clock jumped over because nothing could happen (equal results to ticking).
    pub skipped_cycles: u64,
    /// Ray start and end (`[bricks]`, `[clip]`, `[geometry]`): positions cut, ray-setup
    /// traversal cycles, start/end table; absent when all are off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ray_range: Option<RayRangeStats>,
}

pub struct CycleResult {
    pub frame: Frame,
    pub stats: CycleStats,
}

/// Compositing-side state of one ray.
#[derive(Clone, Copy, Default)]
struct RayProgress {
    acc: Accumulator,
    /// Headlight direction for shading (from ray setup).
    light: [i32; 3],
    /// Opaque surface composited behind instead of the background (geometry).
    surface: Option<[u32; 4]>,
    /// Sample positions of the ray.
    positions: u32,
    /// Reached the ERT threshold at the compositing stage.
    terminated: bool,
    /// Samples composited or discarded.
    done: u32,
    /// Samples the ray queue issued in total, known once the ray left the queue.
    issued_total: Option<u32>,
    retired: bool,
}

/// A sample inside the interpolation..compositing stages.
#[derive(Clone, Copy)]
struct StagedSample {
    due: u64,
    ray_id: usize,
    k: u64,
    pos: [i64; 3],
    value: SampleValue,
}

/// How a simulation runs and what it records besides its result.
pub struct SimOptions<'a> {
    /// Jump over cycles in which nothing can happen (same results as ticking every cycle, only
    /// faster). Default true.
    pub skip_dead_cycles: bool,
    /// Record the signals of the waveform's cycle window into its VCD file.
    pub waveform: Option<&'a mut Waveform>,
    /// Write every memory command of the trace's cycle window (nothing with a memory model
    /// without commands). The simulation also tells the trace the cycle it ended at.
    pub command_trace: Option<&'a mut CommandTrace>,
    /// Simulate only these rays (pixel indices), in this issue order, instead of the whole
    /// frame in tile order: a segment of a sampled simulation (`arch::sampling`). The result's
    /// frame is then a strip of the subset's pixels in this order (width = rays, height 1).
    pub rays: Option<&'a [usize]>,
    /// Snapshots at given ray admissions (unit boundaries of a sampled simulation).
    pub checkpoints: Option<&'a mut Checkpoints>,
}

/// Where a simulation takes snapshots: when the ray at each position of the issue order enters
/// the ray queue (a position equal to the number of rays: when the last pixel is written).
/// Admission times telescope: the cycles between the admissions of rays a and b depend only on
/// the rays before b, so a segment that stops at b's admission measures them exactly as the
/// whole frame would, given the same state at a.
#[derive(Debug, Default)]
pub struct Checkpoints {
    /// Positions in the issue order, ascending.
    pub at: Vec<usize>,
    /// End the simulation at the last checkpoint instead of running to the frame's end.
    pub stop_at_last: bool,
    /// One snapshot per position of `at`, in order.
    pub taken: Vec<Checkpoint>,
}

/// The pipeline's and the memory's counters at one ray admission.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    /// The cycle of the admission (cycles before it are fully accounted in `stats`).
    pub cycle: u64,
    pub stats: CycleStats,
    /// The memory's statistics (`VoxelMemory::stats_json`).
    pub memory: serde_json::Value,
}

impl Checkpoints {
    fn due(&self, position: usize) -> bool {
        self.at.get(self.taken.len()) == Some(&position)
    }

    fn take<M: VoxelMemory>(&mut self, now: u64, stats: &CycleStats, memory: &M) {
        let mut stats = stats.clone();
        stats.cycles = now;
        self.taken.push(Checkpoint {
            cycle: now,
            stats,
            memory: memory.stats_json(),
        });
    }

    fn complete(&self) -> bool {
        self.taken.len() == self.at.len()
    }
}

impl Default for SimOptions<'_> {
    fn default() -> Self {
        SimOptions {
            skip_dead_cycles: true,
            waveform: None,
            command_trace: None,
            rays: None,
            checkpoints: None,
        }
    }
}

/// Simulates one frame. `skipper` is the space-skipping strategy (shared with the functional
/// model), `memory` the voxel memory model. `skip_dead_cycles`: jump over cycles in which
/// nothing can happen (same results as ticking every cycle, only faster). `waveform`: record
/// the signals of its cycle window into a VCD file. (`simulate_with` takes the options as one
/// struct and can also write a command trace.)
pub fn simulate<S: SpaceSkipper, M: VoxelMemory>(
    renderer: &FixedRenderer,
    camera: &Camera,
    skipper: &S,
    memory: &mut M,
    config: &HardwareConfig,
    skip_dead_cycles: bool,
    waveform: Option<&mut Waveform>,
) -> Result<CycleResult> {
    simulate_with(
        renderer,
        camera,
        skipper,
        memory,
        config,
        SimOptions {
            skip_dead_cycles,
            waveform,
            command_trace: None,
            rays: None,
            checkpoints: None,
        },
    )
}

/// Simulates one frame with the given options (see `SimOptions`).
pub fn simulate_with<S: SpaceSkipper, M: VoxelMemory>(
    renderer: &FixedRenderer,
    camera: &Camera,
    skipper: &S,
    memory: &mut M,
    config: &HardwareConfig,
    options: SimOptions<'_>,
) -> Result<CycleResult> {
    let SimOptions {
        skip_dead_cycles,
        mut waveform,
        mut command_trace,
        rays,
        mut checkpoints,
    } = options;
    let mut issued_commands: Vec<IssuedCommand> = Vec::new();
    memory.record_commands(command_trace.is_some() || waveform.is_some());
    let (w, h) = (camera.width, camera.height);
    // A ray's id indexes the per-ray state: its pixel for the whole frame, its position in
    // `rays` for a subset.
    let (ray_count, order) = match rays {
        None => ((w * h) as usize, tile_order(w, h, config.ray_queue.tile)),
        Some(rays) => (rays.len(), (0..rays.len()).collect()),
    };
    let pixel_of = |ray_id: usize| rays.map_or(ray_id, |r| r[ray_id]);
    // Rays admitted to the ray queue so far (position in the issue order of the next one).
    let mut admitted = 0usize;
    let mut stopped = false;
    let mut pixels = vec![[0u8; 4]; ray_count];
    let mut records = vec![RayRecord::default(); ray_count];
    let mut progress = vec![RayProgress::default(); ray_count];
    let mut written = vec![false; ray_count];

    let mut queue = RayQueue::new(config.ray_queue.rays, config.ray_queue.selection);
    let mut skip = SkipUnit::new(config.skip.latency);
    let mut buffer = CompositingBuffer::new(config.compositing.buffer_capacity, ray_count);
    let mut stages: VecDeque<StagedSample> = VecDeque::new();
    let mut feedback: VecDeque<(u64, usize)> = VecDeque::new();
    let mut completed_tags = Vec::new();
    let mut leaving_candidates: Vec<usize> = Vec::new();
    // Distance-volume leaping: (slot, voxel) whose distance word must be read before the ray
    // at its current position may issue; the slot stays busy until the word is back.
    let mut word_requests: VecDeque<(usize, [usize; 3])> = VecDeque::new();
    let mut waiting_words = 0usize;
    // Leap values: per compositing-buffer tag, the position update of a step whose advance
    // comes from that sample's words; it enters the skip unit when they are back.
    let mut held_updates: Vec<Option<PositionUpdate>> =
        vec![None; config.compositing.buffer_capacity];
    let mut waiting_samples = 0usize;
    let mut next_setup = 0usize;
    // Rays in the setup units, in pixel order: (ray id, its setup, cycle it is ready).
    let mut in_setup: VecDeque<(usize, crate::functional::setup::FixedRay, u64)> = VecDeque::new();
    let setup_units = if config.bricks.is_off() {
        1
    } else {
        config.bricks.setup_units as usize
    };
    let mut retired = 0usize;

    let stage_latency = config.compositing.stage_latency as u64;
    let feedback_latency = config.compositing.ert_feedback_latency as u64;
    let compositor = &renderer.compositor;
    let mut stats = CycleStats {
        rays: ray_count as u64,
        ray_queue_occupancy: vec![0; config.ray_queue.rays + 1],
        compositing_buffer_occupancy: vec![0; config.compositing.buffer_capacity + 1],
        ray_range: renderer.ray_range.as_ref().map(|_| {
            let traversal = setup_cycles_on(config);
            RayRangeStats {
                setup_cycles: traversal.then_some(0),
                bricks_visited: traversal.then_some(0),
                ..RayRangeStats::default()
            }
        }),
        ..Default::default()
    };
    let mut last_progress = 0u64;
    // The watchdog fires after `watchdog_cycles` without progress on top of the longest legal
    // wait: the memory's bound plus the pipeline's own latencies.
    let watchdog = config.compositing.watchdog_cycles
        + memory.longest_legal_wait()
        + config.skip.latency as u64
        + stage_latency
        + feedback_latency;
    let mut now = 0u64;

    // Retires a ray whose every issued sample is composited or discarded.
    let try_retire = |ray_id: usize,
                      progress: &mut [RayProgress],
                      pixels: &mut [[u8; 4]],
                      written: &mut [bool],
                      retired: &mut usize| {
        let p = &mut progress[ray_id];
        if !p.retired && p.issued_total == Some(p.done) {
            p.retired = true;
            pixels[ray_id] = compositor.finish_ray(&p.acc, p.surface);
            debug_assert!(!written[ray_id], "pixel {ray_id} written twice");
            written[ray_id] = true;
            *retired += 1;
        }
    };

    let mut probe = Probe::default();
    'clock: while retired < ray_count {
        let mut moved = false;
        let retired_before = retired;
        let mut ert_event = false;

        // Compositing stages: the sample due now is composited, or discarded after ERT.
        while let Some(s) = stages.front().copied() {
            if s.due > now {
                break;
            }
            stages.pop_front();
            moved = true;
            let p = &mut progress[s.ray_id];
            if p.terminated {
                stats.discarded_after_ert += 1;
            } else {
                let rgba = renderer.classify_value(s.pos, s.value, p.light);
                stats.composited += 1;
                let steps = s.value.steps();
                if compositor.composite_steps(&mut p.acc, rgba, steps as u32) {
                    p.terminated = true;
                    // As in the functional model: early if positions remained after those
                    // this sample stands for.
                    records[s.ray_id].terminated_early = s.k + steps < p.positions as u64;
                    feedback.push_back((now + feedback_latency, s.ray_id));
                    ert_event = true;
                }
            }
            p.done += 1;
            try_retire(
                s.ray_id,
                &mut progress,
                &mut pixels,
                &mut written,
                &mut retired,
            );
        }

        // Compositing buffer: release one sample, oldest of its ray, into the stages.
        if let Some(s) = buffer.release() {
            stages.push_back(StagedSample {
                due: now + stage_latency,
                ray_id: s.ray_id,
                k: s.k,
                pos: s.pos,
                value: s.value,
            });
            moved = true;
        }

        // Voxel memory: samples whose words are all in.
        completed_tags.clear();
        memory.step(now, &mut completed_tags);
        if let Some(trace) = command_trace.as_deref_mut().filter(|t| t.wants(now)) {
            issued_commands.clear();
            memory.issued_commands(now, &mut issued_commands);
            for c in &issued_commands {
                trace.record(c)?;
            }
        }
        for &tag in &completed_tags {
            moved = true;
            if tag & WORD_TAG != 0 {
                // A distance word is back: its ray may issue (or leave, if ERT came meanwhile).
                let index = (tag & !WORD_TAG) as usize;
                if let Some(slot) = queue.slot_mut(index) {
                    slot.busy = false;
                }
                waiting_words -= 1;
                leaving_candidates.push(index);
                continue;
            }
            // Leap values: the words tell how far the ray goes; its update may now be computed.
            if let Some(update) = held_updates[tag as usize].take() {
                skip.push(update, now);
                waiting_samples -= 1;
            }
            buffer.arrive(tag as u32);
        }

        // ERT feedback reaching the ray queue.
        while let Some(&(due, ray_id)) = feedback.front() {
            if due > now {
                break;
            }
            feedback.pop_front();
            leaving_candidates.extend(queue.terminate(ray_id));
            moved = true;
        }

        // Skip unit results back in the ray queue.
        if let Some(update) = skip.pop_ready(now) {
            if let Some(slot) = queue.slot_mut(update.slot) {
                slot.pos = update.pos;
                slot.k = update.k;
                slot.busy = false;
                // With a structure in volume memory, the new position's word is read first
                // (not at an iso refinement midpoint: the ray samples it whatever the word).
                if !slot.finished() && slot.state.bisection.is_none() {
                    if let Some(voxel) = skipper.memory_word(slot.pos) {
                        slot.busy = true;
                        waiting_words += 1;
                        word_requests.push_back((update.slot, voxel));
                    }
                }
                leaving_candidates.push(update.slot);
            }
            moved = true;
        }
        // Rays that have issued their last position (or learnt of ERT) leave the queue. Only a
        // slot whose update came back or whose ray was terminated can have become finished.
        for i in leaving_candidates.drain(..) {
            let leaving = queue.slot(i).is_some_and(|s| !s.busy && s.finished());
            if leaving {
                let slot = queue.remove(i).expect("slot present");
                let p = &mut progress[slot.ray_id];
                p.issued_total = Some(slot.samples_issued);
                try_retire(
                    slot.ray_id,
                    &mut progress,
                    &mut pixels,
                    &mut written,
                    &mut retired,
                );
                moved = true;
            }
        }

        // Distance words: one read enters the memory per cycle, in request order.
        if let Some(&(index, voxel)) = word_requests.front() {
            if memory.try_push_word(WORD_TAG | index as u64, voxel, now) {
                word_requests.pop_front();
                stats.distance_reads += 1;
                moved = true;
            }
        }

        // Issue: one step of one ready ray.
        let issued = issue(
            renderer,
            &mut queue,
            &mut skip,
            &mut buffer,
            memory,
            skipper,
            &mut records,
            &mut stats,
            now,
            &mut held_updates,
            &mut waiting_samples,
            waiting_words > 0,
        );
        moved |= issued.is_ok();
        let stall = issued.err();

        // Ray setup: fill free slots; rays that miss the volume write the background at once.
        // With `bricks.setup = "traversal"` each of `bricks.setup_units` units works on one ray
        // at a time, taking `setup_cycles` (per ray + per brick visited) before the ray may
        // enter the queue (in pixel order), so a slow setup starves the queue
        // (`ray_queue_empty`). Without it a ray is ready at once.
        for _ in 0..config.ray_queue.setups_per_cycle {
            while in_setup.len() < setup_units && next_setup < ray_count {
                let ray_id = order[next_setup];
                next_setup += 1;
                let pixel = pixel_of(ray_id) as u32;
                let (px, py) = (pixel % w, pixel / w);
                let ray = renderer.setup(camera, px, py);
                let cost = setup_cycles(config, &ray);
                if let Some(r) = stats.ray_range.as_mut() {
                    r.setup_cycles = r.setup_cycles.map(|c| c + cost);
                    r.bricks_visited = r.bricks_visited.map(|b| b + ray.bricks_visited as u64);
                }
                in_setup.push_back((ray_id, ray, now + cost));
            }
            // Only the ready cycle is read here: the ray (some 200 bytes) is moved out when it
            // is admitted, not copied every cycle it waits.
            let Some(&(_, _, ready)) = in_setup.front() else {
                break;
            };
            if ready > now {
                break;
            }
            let Some(free) = queue.free_slot() else { break };
            if let Some(c) = checkpoints.as_deref_mut().filter(|c| c.due(admitted)) {
                c.take(now, &stats, memory);
                if c.stop_at_last && c.complete() {
                    stopped = true;
                    break 'clock;
                }
            }
            admitted += 1;
            let (ray_id, ray, _) = in_setup.pop_front().expect("the front was read above");
            moved = true;
            records[ray_id] = RayRecord {
                hit: ray.samples > 0,
                first_sample: ray.first_k,
                end_sample: ray.first_k + ray.samples as i64,
                positions_cut: ray.cut,
                t_enter: ray.t_range[0],
                t_exit: ray.t_range[1],
                ..RayRecord::default()
            };
            progress[ray_id].light = ray.light;
            progress[ray_id].surface = ray.surface;
            progress[ray_id].positions = ray.samples;
            if ray.samples == 0 {
                progress[ray_id].issued_total = Some(0);
                try_retire(
                    ray_id,
                    &mut progress,
                    &mut pixels,
                    &mut written,
                    &mut retired,
                );
                continue;
            }
            // With a structure in volume memory, the first position's word is read first.
            let word = skipper.memory_word(ray.start);
            if let Some(voxel) = word {
                waiting_words += 1;
                word_requests.push_back((free, voxel));
            }
            queue.admit(
                free,
                RaySlot {
                    ray_id,
                    pos: ray.start,
                    ray,
                    k: 0,
                    busy: word.is_some(),
                    terminated: false,
                    admitted: now,
                    samples_issued: 0,
                    state: SkipState::default(),
                },
            );
        }

        if let Some(w) = waveform.as_deref_mut().filter(|w| w.wants(now)) {
            probe.ray_queue_occupancy = queue.occupancy() as u64;
            probe.issue_valid = issued.is_ok();
            if let Ok(step) = issued {
                probe.issue_ray = step.ray_id as u64;
                probe.leap = step.leap;
                probe.occupied = !step.leap;
            }
            probe.compositing_buffer = buffer.len() as u64;
            probe.ert_event = ert_event;
            probe.retire_event = retired > retired_before;
            memory.probe(&mut probe.modules);
            w.sample(now, &probe)?;
        }

        // Account this cycle, then jump over cycles in which nothing can happen (not while a
        // waveform records: every cycle of its window is written).
        let recording = waveform.as_deref().is_some_and(|w| w.wants(now + 1));
        let mut span = 1u64;
        if moved {
            last_progress = now;
        } else {
            // The pipeline's own timed events (a skip result, a stage, ERT feedback, a ray
            // leaving setup) each move something when they come: while one is pending, the
            // pipeline is waiting, not stuck, however long (a slow brick traversal).
            let pipeline_next = [
                skip.next_event(),
                stages.front().map(|s| s.due),
                feedback.front().map(|&(due, _)| due),
                in_setup
                    .front()
                    .map(|&(_, _, ready)| ready)
                    .filter(|&t| t > now),
            ]
            .into_iter()
            .flatten()
            .min();
            let next = pipeline_next
                .into_iter()
                .chain(memory.next_event(now))
                .min();
            match next {
                Some(t) if skip_dead_cycles && !recording && t > now + 1 => span = t - now,
                Some(_) => {}
                None if retired < ray_count => {
                    return Err(deadlock(
                        now,
                        &queue,
                        &buffer,
                        &stages,
                        memory,
                        "nothing is pending",
                    ))
                }
                None => {}
            }
            if pipeline_next.is_some() {
                last_progress = now;
            } else if now + span - last_progress > watchdog {
                return Err(deadlock(
                    now,
                    &queue,
                    &buffer,
                    &stages,
                    memory,
                    &format!(
                        "watchdog: no progress for {} cycles, the longest legal wait of this \
                         configuration plus compositing.watchdog_cycles",
                        watchdog
                    ),
                ));
            }
        }
        if let Some(cause) = stall {
            match cause {
                Stall::RayQueueEmpty => stats.stall_cycles.ray_queue_empty += span,
                Stall::SkipBusy => stats.stall_cycles.skip_unit_busy += span,
                Stall::Memory => stats.stall_cycles.memory += span,
                Stall::BufferFull => stats.stall_cycles.compositing_buffer_full += span,
                Stall::DistanceWord => stats.stall_cycles.distance_word += span,
                Stall::LeapWord => stats.stall_cycles.leap_word += span,
            }
        }
        stats.ray_queue_occupancy[queue.occupancy()] += span;
        stats.compositing_buffer_occupancy[buffer.len()] += span;
        memory.account_cycles(span);
        stats.skipped_cycles += span - 1;
        now += span;
    }
    stats.cycles = now;
    let frame_size = match rays {
        None => (w, h),
        Some(_) => (ray_count as u32, 1),
    };
    if let Some(c) = checkpoints.filter(|c| c.due(ray_count)) {
        c.take(now, &stats, memory);
    }
    let result = |pixels, records, stats| CycleResult {
        frame: Frame {
            width: frame_size.0,
            height: frame_size.1,
            pixels,
            rays: records,
        },
        stats,
    };
    if stopped {
        // A segment ended at its last checkpoint: rays still in flight, nothing to check.
        return Ok(result(pixels, records, stats));
    }
    if let Some(r) = stats.ray_range.as_mut() {
        let totals = RayRangeStats::from_records(&records);
        r.positions_in_box = totals.positions_in_box;
        r.positions_in_range = totals.positions_in_range;
        r.positions_cut = totals.positions_cut;
        // The start/end table is loaded from the host before the first ray is set up: its
        // cycles come first in the frame, the pipeline idle. They are added here rather than
        // simulated, so cycle numbers in waveforms and traces start after the load and the
        // memory's refreshes during it are not modelled.
        if let Some((bytes, load)) = table_cost(config, ray_count as u64) {
            r.table_bytes = Some(bytes);
            r.table_load_cycles = Some(load);
            stats.cycles += load;
            stats.ray_queue_occupancy[0] += load;
            stats.compositing_buffer_occupancy[0] += load;
        }
    }
    if let Some(trace) = command_trace {
        trace.end(now);
    }
    stats.rays_terminated_early = records.iter().filter(|r| r.terminated_early).count() as u64;

    // Conservation (brief, section 5 (e)): every issued sample composited once or discarded.
    if stats.samples != stats.composited + stats.discarded_after_ert || !written.iter().all(|&x| x)
    {
        return Err(Error::Invalid(format!(
            "internal invariant broken: {} samples issued, {} composited, {} discarded, {} of {} pixels written",
            stats.samples,
            stats.composited,
            stats.discarded_after_ert,
            written.iter().filter(|&&x| x).count(),
            ray_count
        )));
    }
    Ok(result(pixels, records, stats))
}

/// Whether ray setup traverses the brick grid (its cycles are counted).
fn setup_cycles_on(config: &HardwareConfig) -> bool {
    !config.bricks.is_off() && config.bricks.setup == crate::config::BrickSetup::Traversal
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stall {
    RayQueueEmpty,
    SkipBusy,
    Memory,
    BufferFull,
    DistanceWord,
    LeapWord,
}

/// What the issue stage did in a cycle.
#[derive(Clone, Copy, Debug)]
struct Issued {
    ray_id: usize,
    /// A leap-only step, or a sample followed by a leap.
    leap: bool,
}

/// The issue stage: selects one ready ray and issues its step, or says why nothing issued.
#[allow(clippy::too_many_arguments)]
fn issue<S: SpaceSkipper, M: VoxelMemory>(
    renderer: &FixedRenderer,
    queue: &mut RayQueue,
    skip: &mut SkipUnit,
    buffer: &mut CompositingBuffer,
    memory: &mut M,
    skipper: &S,
    records: &mut [RayRecord],
    stats: &mut CycleStats,
    now: u64,
    held_updates: &mut [Option<PositionUpdate>],
    waiting_samples: &mut usize,
    waiting_words: bool,
) -> std::result::Result<Issued, Stall> {
    if queue.occupancy() == 0 {
        return Err(Stall::RayQueueEmpty);
    }
    let Some(index) = queue.select() else {
        return Err(if waiting_words {
            Stall::DistanceWord
        } else if *waiting_samples > 0 {
            Stall::LeapWord
        } else {
            Stall::SkipBusy
        });
    };
    let slot = queue.slot_mut(index).expect("selected slot");
    let remaining = slot.ray.samples as u64 - slot.k;
    let ray_id = slot.ray_id;
    // The same step the functional model takes at this position (sample or not, advance);
    // the ray's state changes only if the step issues.
    let mut state = slot.state;
    let step = renderer.step(skipper, slot.pos, &slot.ray, &mut state, remaining);
    let mut held_tag = None;
    if step.sample {
        if buffer.is_full() {
            return Err(Stall::BufferFull);
        }
        // The tag is the compositing-buffer entry the sample will occupy.
        let tag = buffer.next_free().expect("buffer has room: checked above");
        let request = SampleRequest {
            tag: tag as u64,
            base: renderer.base_voxel(slot.pos),
        };
        if !memory.try_push(request, now) {
            return Err(Stall::Memory);
        }
        let id = buffer.reserve(
            slot.ray_id,
            slot.k,
            state.sample_position(step.value, slot.pos),
            step.value,
        );
        debug_assert_eq!(id, Some(tag));
        slot.samples_issued += 1;
        held_tag = step.waits_for_words.then_some(tag);
    }
    slot.state = state;
    step.record(&mut records[slot.ray_id]);
    stats.samples += step.sample as u64;
    stats.leaps += !step.sample as u64;
    stats.leap_samples += step.is_leap_sample() as u64;
    stats.refinement_samples += step.refinement as u64;
    // The skip unit carries P + advance·V back (a leap after a sample included) after its
    // latency, exactly as for any other step; in iso mode a bisection midpoint instead, or the
    // end of the ray once its surface is found.
    let new_k = if step.ends_ray {
        slot.ray.samples as u64
    } else {
        slot.k + step.advance
    };
    let new_pos = if step.bisects {
        state.midpoint()
    } else {
        add_steps(slot.pos, slot.ray.step, step.advance)
    };
    stats.steps += 1;
    slot.busy = true;
    let update = PositionUpdate {
        slot: index,
        pos: new_pos,
        k: new_k,
    };
    match held_tag {
        // The advance is in the sample's words: the update waits for them.
        Some(tag) => {
            held_updates[tag as usize] = Some(update);
            *waiting_samples += 1;
        }
        None => skip.push(update, now),
    }
    queue.issued_from(index);
    Ok(Issued {
        ray_id,
        // For the waveform: the occupancy lookup found an empty sub-cube and the ray leaps
        // (with or without a sample first).
        leap: !step.sample || step.is_leap_sample(),
    })
}

#[inline]
fn add_steps(pos: [i64; 3], step: [i64; 3], n: u64) -> [i64; 3] {
    [0, 1, 2].map(|a| pos[a] + n as i64 * step[a])
}

fn deadlock<M: VoxelMemory>(
    now: u64,
    queue: &RayQueue,
    buffer: &CompositingBuffer,
    stages: &VecDeque<StagedSample>,
    memory: &M,
    why: &str,
) -> Error {
    // A readable dump: a few lines, not every slot and every module's counters.
    const SHOWN: usize = 8;
    let mut text = format!("pipeline deadlock at cycle {now} ({why})\n");
    let slots: Vec<_> = queue.slots().collect();
    text += &format!("  ray queue: {} rays\n", slots.len());
    for s in slots.iter().take(SHOWN) {
        text += &format!(
            "    ray {} at position {}{}{}\n",
            s.ray_id,
            s.k,
            if s.busy { ", busy" } else { "" },
            if s.terminated { ", terminated" } else { "" }
        );
    }
    if slots.len() > SHOWN {
        text += &format!("    ... and {} more\n", slots.len() - SHOWN);
    }
    text += &format!(
        "  compositing buffer: {} entries; samples in the stages: {}\n",
        buffer.len(),
        stages.len()
    );
    let mut stats = memory.stats_json();
    if let Some(modules) = stats.as_object_mut().and_then(|m| m.remove("modules")) {
        let count = modules.as_array().map_or(0, Vec::len);
        text += &format!("  memory ({count} modules; per-module counters left out): ");
    } else {
        text += "  memory: ";
    }
    text += &stats.to_string();
    Error::Invalid(text)
}

/// Pixel order: tiles of `tile` pixels, row-major inside a tile and across tiles.
pub fn tile_order(width: u32, height: u32, tile: [u32; 2]) -> Vec<usize> {
    let [tw, th] = tile;
    let mut order = Vec::with_capacity((width * height) as usize);
    for ty in (0..height).step_by(th as usize) {
        for tx in (0..width).step_by(tw as usize) {
            for y in ty..(ty + th).min(height) {
                for x in tx..(tx + tw).min(width) {
                    order.push((y * width + x) as usize);
                }
            }
        }
    }
    order
}
