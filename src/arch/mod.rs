//! The cycle-accurate model: one module per hardware unit (brief, section 4), each a struct with
//! its own state, bounded queues and a per-cycle step; `pipeline` only wires them and runs the
//! clock. Arithmetic comes from the functional model.

pub mod address_map;
pub mod block_lookup;
pub mod command_trace;
pub mod compositing_buffer;
pub mod overtaking_fifo;
pub mod pipeline;
pub mod ray_queue;
pub mod sampling;
pub mod sdram;
pub mod sdram_module;
pub mod skip_unit;
pub mod trace;
pub mod update;
pub mod voxel_memory;
