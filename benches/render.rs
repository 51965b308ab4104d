//! Renderer throughput. Run: `cargo bench --bench render`.
//!
//! `float_256`: the float reference on a 256^3 volume (aneurism when the data folder is there,
//! else the 256^3 sphere phantom), 256x256, one sample per voxel distance, no ERT, one thread
//! (the per-core figure). divan reports samples per second as its item throughput.
//! `float_256_packet`: the same frame with each packet width of the float reference.
//! `cycle_256`: the cycle model (pipeline and SDRAM) on the same volume, 128x128, orbit 5/72;
//! `memory_256`: the SDRAM model alone on that frame's recorded requests. Both report simulated
//! cycles per second.

use std::sync::OnceLock;

use divan::counter::ItemsCount;
use vizsim::camera::{Camera, Projection, View};
use vizsim::render::float::FloatRenderer;
use vizsim::render::RenderSettings;
use vizsim::transfer;
use vizsim::volume::{dataset, Volume};

fn main() {
    divan::main();
}

fn volume_256() -> &'static Volume {
    static VOLUME: OnceLock<Volume> = OnceLock::new();
    VOLUME.get_or_init(|| {
        let dir = dataset::data_dir(None)
            .or_else(|| Some(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data").into()));
        dataset::load("aneurism", dir.as_deref())
            .unwrap_or_else(|_| dataset::load("phantom:sphere:256", None).expect("phantom"))
    })
}

/// A rayon pool of one thread: the benchmarks' figures are per thread.
fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
}

/// The benchmarks' view: frame 5 of a 72-frame orbit, orthographic, size × size pixels.
fn orbit_camera(volume: &Volume, size: u32) -> Camera {
    Camera::for_volume(
        glam::Vec3::from(volume.extent()),
        View::Orbit { k: 5, n: 72 },
        Projection::Ortho,
        size,
        size,
    )
    .unwrap()
}

#[divan::bench(sample_count = 5)]
fn float_256(bencher: divan::Bencher) {
    bench_float(bencher, vizsim::render::float::DEFAULT_PACKET_WIDTH);
}

/// The same frame with each packet width (rays marched together); the image is the same.
#[divan::bench(sample_count = 5, args = vizsim::render::float::PACKET_WIDTHS)]
fn float_256_packet(bencher: divan::Bencher, width: usize) {
    bench_float(bencher, width);
}

fn bench_float(bencher: divan::Bencher, width: usize) {
    let volume = volume_256();
    let tf = transfer::resolve("class", &volume.name).unwrap();
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let renderer = FloatRenderer::new(volume, &tf, &settings)
        .and_then(|r| r.with_packet_width(width))
        .unwrap();
    let camera = orbit_camera(volume, 256);
    let pool = one_thread();
    let samples = pool.install(|| renderer.render(&camera)).stats().samples;
    println!(
        "float_256 (packets of {width}): {} on 1 thread, {samples} samples per frame",
        volume.name
    );
    bencher
        .counter(ItemsCount::new(samples))
        .bench(|| pool.install(|| renderer.render(&camera)));
}

/// Invariant (c)'s predicted bound (`vizsim::bound`) of the same frame, one thread; divan's
/// items are the float frame's samples (the bound visits each once). With and without ERT and
/// shading: the check `--check-bound` adds to a run.
#[divan::bench(sample_count = 5, args = ["plain", "ert", "shading"])]
fn bound_256(bencher: divan::Bencher, mode: &str) {
    let volume = volume_256();
    let tf = transfer::resolve("class", &volume.name).unwrap();
    let settings = RenderSettings {
        ert_threshold: (mode != "plain").then_some(0.95),
        shading: mode == "shading",
        ..Default::default()
    };
    let config = vizsim::config::HardwareConfig::default_config();
    let bound = vizsim::bound::ErrorBound::new(volume, &tf, &settings, &config).unwrap();
    let camera = orbit_camera(volume, 256);
    let samples = FloatRenderer::new(volume, &tf, &settings)
        .unwrap()
        .render(&camera)
        .stats()
        .samples;
    let pool = one_thread();
    println!(
        "bound_256 ({mode}): {} on 1 thread, {samples} float samples per frame",
        volume.name
    );
    bencher
        .counter(ItemsCount::new(samples))
        .bench(|| pool.install(|| bound.predict(&camera)));
}

/// The functional fixed-point model, same frame; divan's items are steps (samples + leaps).
/// `subcube` 0 = no leaping.
#[divan::bench(sample_count = 5, args = [0, 8])]
fn fixed_256(bencher: divan::Bencher, subcube: usize) {
    let mut config = vizsim::config::HardwareConfig::default_config();
    config.occupancy.subcube = subcube;
    bench_fixed(bencher, &config, &format!("fixed_256 (subcube {subcube})"));
}

/// The functional fixed-point model with the leaping structures kept in volume memory, same
/// frame; divan's items are steps. Preprocessing (segmentation, distance transforms) is done
/// once, outside the timed loop.
#[divan::bench(sample_count = 5, args = ["leapvalues", "leapvalues-homogeneous", "distance8"])]
fn fixed_256_in_memory(bencher: divan::Bencher, structure: &str) {
    use vizsim::config::{HardwareConfig, LeapRegions, LeapStructure};
    let mut config = HardwareConfig::default_config();
    match structure {
        "distance8" => config.occupancy.structure = LeapStructure::Distance,
        _ => {
            config.occupancy.structure = LeapStructure::LeapValues;
            if structure == "leapvalues-homogeneous" {
                config.leap_values.regions = LeapRegions::Homogeneous;
            }
        }
    }
    bench_fixed(
        bencher,
        &config,
        &format!("fixed_256_in_memory ({structure})"),
    );
}

/// One thread renders the orbit frame 5/72 of the 256³ volume at 256×256, no ERT, with the
/// leaping `config` selects; divan counts steps.
fn bench_fixed(bencher: divan::Bencher, config: &vizsim::config::HardwareConfig, label: &str) {
    use vizsim::functional::renderer::{FixedRenderer, Leaping};
    let volume = volume_256();
    let tf = transfer::resolve("class", &volume.name).unwrap();
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let renderer =
        FixedRenderer::new(volume, &tf, &settings, config, Leaping::from_config(config)).unwrap();
    let camera = orbit_camera(volume, 256);
    let pool = one_thread();
    let steps = pool.install(|| renderer.render(&camera)).stats().steps();
    println!(
        "{label}: {} on 1 thread, {steps} steps per frame",
        volume.name
    );
    bencher
        .counter(ItemsCount::new(steps))
        .bench(|| pool.install(|| renderer.render(&camera)));
}

/// The SDRAM memory behind the pipeline, recording the sample requests it accepts (not the
/// one-word reads of a distance volume: `memory_256`'s frame has none, and checks it).
struct Recording<M> {
    memory: M,
    requests: Vec<vizsim::arch::voxel_memory::SampleRequest>,
}

impl<M: vizsim::arch::voxel_memory::VoxelMemory> vizsim::arch::voxel_memory::VoxelMemory
    for Recording<M>
{
    fn try_push(&mut self, request: vizsim::arch::voxel_memory::SampleRequest, now: u64) -> bool {
        let entered = self.memory.try_push(request, now);
        if entered {
            self.requests.push(request);
        }
        entered
    }
    fn try_push_word(&mut self, tag: u64, voxel: [usize; 3], now: u64) -> bool {
        self.memory.try_push_word(tag, voxel, now)
    }
    fn step(&mut self, now: u64, completed: &mut Vec<u64>) {
        self.memory.step(now, completed)
    }
    fn is_idle(&self) -> bool {
        self.memory.is_idle()
    }
    fn account_cycles(&mut self, cycles: u64) {
        self.memory.account_cycles(cycles)
    }
    fn next_event(&self, now: u64) -> Option<u64> {
        self.memory.next_event(now)
    }
    fn stats_json(&self) -> serde_json::Value {
        self.memory.stats_json()
    }
    fn longest_legal_wait(&self) -> u64 {
        self.memory.longest_legal_wait()
    }
    fn record_commands(&mut self, on: bool) {
        self.memory.record_commands(on)
    }
    fn probe(&self, modules: &mut Vec<vizsim::arch::trace::ModuleProbe>) {
        self.memory.probe(modules)
    }
    fn issued_commands(&self, now: u64, out: &mut Vec<vizsim::arch::command_trace::IssuedCommand>) {
        self.memory.issued_commands(now, out)
    }
}

/// `memory_256`: the SDRAM model alone. `cycle_256`'s frame is simulated once with its memory
/// recording the sample requests it accepts, in order; each iteration replays them on a fresh
/// memory, one cycle at a time: step the memory, then enter the next request if its
/// compositing-buffer tag is free again and every module has room. The replay has about the
/// frame's cycles and reads, without the pipeline's work, so divan's item throughput
/// (simulated cycles per second) is what the memory side alone costs per cycle.
#[divan::bench(sample_count = 5)]
fn memory_256(bencher: divan::Bencher) {
    use vizsim::arch::pipeline::simulate;
    use vizsim::arch::voxel_memory::VoxelMemory;
    let (config, renderer, camera) = cycle_frame();
    let mut recording = Recording {
        memory: cycle_memory(&config),
        requests: Vec::new(),
    };
    let frame = simulate(
        &renderer,
        &camera,
        &renderer.skipper(),
        &mut recording,
        &config,
        true,
        None,
    )
    .unwrap()
    .stats;
    assert_eq!(frame.distance_reads, 0, "only sample requests are recorded");
    let frame_cycles = frame.cycles;
    let requests = recording.requests;
    let words_per_request = config.memory.modules() as u64;
    let replay = || {
        let mut memory = cycle_memory(&config);
        memory.record_commands(false);
        let mut in_flight = vec![false; config.compositing.buffer_capacity];
        let mut completed = Vec::new();
        let (mut now, mut next) = (0u64, 0usize);
        while next < requests.len() || !memory.is_idle() {
            completed.clear();
            memory.step(now, &mut completed);
            for &tag in &completed {
                in_flight[tag as usize] = false;
            }
            if let Some(&request) = requests.get(next) {
                if !in_flight[request.tag as usize] && memory.try_push(request, now) {
                    in_flight[request.tag as usize] = true;
                    next += 1;
                }
            }
            memory.account_cycles(1);
            now += 1;
        }
        assert_eq!(
            memory.stats_json()["reads"].as_u64(),
            Some(words_per_request * requests.len() as u64),
            "every request's words read, one per module"
        );
        now
    };
    let cycles = replay();
    println!(
        "memory_256: {} requests of the cycle_256 frame ({frame_cycles} cycles), replayed in {cycles} cycles",
        requests.len()
    );
    bencher.counter(ItemsCount::new(cycles)).bench(replay);
}

/// `cycle_256`'s frame: the default configuration, the class transfer function, no leaping,
/// 128x128, orbit 5/72.
fn cycle_frame() -> (
    vizsim::config::HardwareConfig,
    vizsim::functional::renderer::FixedRenderer<'static>,
    Camera,
) {
    use vizsim::functional::renderer::{FixedRenderer, Leaping};
    let volume = volume_256();
    let tf = transfer::resolve("class", &volume.name).unwrap();
    let config = vizsim::config::HardwareConfig::default_config();
    let renderer = FixedRenderer::new(
        volume,
        &tf,
        &RenderSettings::default(),
        &config,
        Leaping::None,
    )
    .unwrap();
    let camera = orbit_camera(volume, 128);
    (config, renderer, camera)
}

/// A fresh SDRAM memory for `cycle_256`'s volume at the configuration's clock.
fn cycle_memory(
    config: &vizsim::config::HardwareConfig,
) -> vizsim::arch::sdram_module::SdramMemory {
    vizsim::arch::sdram_module::SdramMemory::new(
        &config.memory,
        &config.sdram,
        volume_256().dims,
        config.clock.frequency_mhz,
    )
}

/// The cycle-accurate pipeline with the SDRAM model (default configuration), one 256³ frame at
/// 128×128 (a 256×256 frame takes four times as long); divan's items are simulated cycles.
#[divan::bench(sample_count = 2)]
fn cycle_256(bencher: divan::Bencher) {
    use vizsim::arch::pipeline::simulate;
    let (config, renderer, camera) = cycle_frame();
    let volume = volume_256();
    let run = || {
        let mut memory = cycle_memory(&config);
        simulate(
            &renderer,
            &camera,
            &renderer.skipper(),
            &mut memory,
            &config,
            true,
            None,
        )
        .unwrap()
    };
    let cycles = run().stats.cycles;
    println!(
        "cycle_256: {} at 128x128, {cycles} cycles per frame",
        volume.name
    );
    bencher.counter(ItemsCount::new(cycles)).bench(run);
}
