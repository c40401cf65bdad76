//! TEMPORARY, until branch `tri-poly` lands: a minimal [`Piece`] impl for
//! [`CubicSegment`] so that `impl Field for Trilinear` compiles on `tri-dual`. Delete this
//! file (and `mod stub;` in `mod.rs`) when merging `tri-poly`, which owns the real impl in
//! `piece.rs`. Constant pieces take [`Segment`]'s closed forms; the polynomial forms of
//! non-constant pieces are left unimplemented here.

use super::{poly, CubicSegment};
use crate::color::Rgb;
use crate::volume::field::{Piece, Segment};

const OWNED_BY_TRI_POLY: &str = "polynomial pieces: impl Piece for CubicSegment lands with branch tri-poly";

impl Piece for CubicSegment {
    fn t0(&self) -> f64 {
        self.t0
    }
    fn t1(&self) -> f64 {
        self.t1
    }
    fn constant(&self) -> Option<Segment> {
        let c = self.corners[0];
        self.constant.then_some(Segment { t0: self.t0, t1: self.t1, density: c.density, source: c.source, albedo: self.albedo[0] })
    }
    fn optical_depth(&self, sigma_t: f64, u: f64) -> f64 {
        let a = &self.density;
        sigma_t * u * (a[0] + u * (a[1] / 2.0 + u * (a[2] / 3.0 + u * a[3] / 4.0)))
    }
    fn free_path(&self, sigma_t: f64, od: f64) -> f64 {
        self.constant().expect(OWNED_BY_TRI_POLY).free_path(sigma_t, od)
    }
    fn density_at(&self, u: f64) -> f32 {
        poly::eval(&self.density, u) as f32
    }
    fn source_at(&self, u: f64) -> f32 {
        self.constant().expect(OWNED_BY_TRI_POLY).source_at(u)
    }
    fn albedo_at(&self, u: f64) -> f32 {
        self.constant().expect(OWNED_BY_TRI_POLY).albedo_at(u)
    }
    fn emission_at(&self, le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3] {
        self.constant().expect(OWNED_BY_TRI_POLY).emission_at(le, u)
    }
    fn emission_integral(&self, le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3] {
        self.constant().expect(OWNED_BY_TRI_POLY).emission_integral(le, u)
    }
}
