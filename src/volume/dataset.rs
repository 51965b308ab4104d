//! Datasets by name.
