//! (placeholder; being written)
/// Sparse brick volume (being written).
pub struct Volume;
