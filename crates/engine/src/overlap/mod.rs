//! Several volumes in one scene: [`volumes::Volumes`], a field whose pieces sum the
//! overlapping volumes' coefficients and emission ([`piece::OverlapPiece`]), and the
//! scattering of a collision among them ([`scattering`]: the albedo and phase mixture of
//! its classes). METHOD.md §14's rule: where volumes overlap, the medium is the sum of
//! their coefficients, so every estimator stays exact or unbiased as it is for one.

pub mod member;
pub mod piece;
pub mod scattering;
pub mod stream;
pub mod volumes;
