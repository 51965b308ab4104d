//! Phantoms generated in code, deterministic from a seed.

use super::Volume;
use crate::error::Result;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhantomKind {
    Sphere,
    Shells,
    Jet,
    Metaballs,
    Cast,
}

#[derive(Clone, Debug, PartialEq)]
pub struct PhantomSpec {
    pub kind: PhantomKind,
    pub size: usize,
    pub seed: u64,
    /// Animation time for the metaballs (other phantoms ignore it).
    pub time: f32,
}

/// Parses the part after `phantom:`, e.g. `sphere:64`, `metaballs:64:t=0.5`, `cast:128:seed=7`.
pub fn parse_spec(text: &str) -> Result<PhantomSpec> {
    let _ = text;
    unimplemented!("phantom spec parser")
}

pub fn generate(spec: &PhantomSpec) -> Volume {
    let _ = spec;
    unimplemented!("phantom generator")
}
