//! What a field made of several overlapping volumes needs from their pieces, as plain
//! data: a piece's values as cubics past a point ([`PieceCubics`], so that pieces of
//! different volumes can be summed over the stretch where they overlap), and a collision's
//! share of each scattering class ([`ClassWeights`], [`ScatterClass`]).
//!
//! Where volumes overlap the medium is the sum of their coefficients: `μ_t = Σ_i μ_t,i`,
//! `L_e = Σ_i L_e,i`, and a collision scatters as the mixture `Σ_i μ_s,i p_i / μ_t`. Volumes
//! whose media scatter alike (the same colour and asymmetry) form one *class*; a collision
//! carries `w_k = μ_k/μ_t` for each class `k`, with `μ_k` the classes' summed reference
//! extinction, and the engine turns the weights into the vertex's albedo and phase mixture.
//! The optics (which class a volume has, its colour and `g`) are the engine's: it passes
//! them in.

/// The most scattering classes a scene may have (volumes whose media scatter alike share
/// one).
pub const MAX_CLASSES: usize = 8;

/// A piece's density and emission density along it from `offset` on, each a cubic in the
/// distance `v = u − offset` (`Σ_j a_j vʲ`; only `a_0` for a constant piece).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceCubics {
    /// Density ρ (grid units).
    pub density: [f64; 4],
    /// Emission density `L_e` per channel (the `le` the piece was handed).
    pub emission: [[f64; 4]; 3],
    /// False when no emission can come from the piece.
    pub emits: bool,
}

/// A collision's share of each scattering class: `w_k = μ_k/μ_t` (in `[0, 1]`, summing to
/// at most 1; the rest is absorbed by volumes whose media do not scatter).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassWeights(pub [f32; MAX_CLASSES]);

/// How one class scatters: the scattering colour (`μ_s,c = C_c μ`) and Henyey–Greenstein's
/// asymmetry `g`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScatterClass {
    /// Scattering colour per channel, in `[0, 1]`.
    pub color: [f32; 3],
    /// Asymmetry in `(−1, 1)`.
    pub g: f64,
}

/// A field of several volumes in which only one light group's volumes emit: the same
/// extinction and scattering, so a walk with the same numbers takes the same path and
/// collects that group's share of the emission (the engine's AOV layers of volume light
/// groups). `layer` is the group's AOV layer.
#[derive(Debug)]
pub struct EmissionGroup<F> {
    /// The group's AOV layer (an index the engine gives).
    pub layer: usize,
    /// The field with only the group's emission.
    pub field: F,
}
