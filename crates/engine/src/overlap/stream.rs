//! The pieces of several volumes along a ray ([`OverlapSegments`]): a k-way merge of the
//! piece streams of the volumes the ray meets (found through the scene's
//! `plume_volume::instance::BoundsIndex`), each walked in its own frame (`instance`), cut wherever any
//! stream's piece ends or a later one starts, and summed ([`OverlapPiece`]).

use plume_core::color::Rgb;
use plume_volume::field::{Field, Piece, PieceCubics, Ray, SegmentIter};

use super::member::Member;
use super::piece::OverlapPiece;
use crate::medium::emission::{EmissionMemo, LeTask};
use plume_volume::instance::to_world;
use plume_volume::instance::BoundsIndex;

/// One volume's stream along a ray: its iterator, the piece it is on, the base distance
/// per world distance (1 but for a scaled instance), and a memo of its emission (a
/// trilinear piece reads 8 corners' `L_e`, mostly the last piece's).
struct Stream<'a, F: Field + 'a> {
    member: usize,
    pieces: F::Segments<'a>,
    piece: F::Piece,
    scale: f64,
    memo: EmissionMemo<'a>,
}

impl<F: Field> Stream<'_, F> {
    /// Where the current piece starts, in world distance.
    #[inline]
    fn t0(&self) -> f64 {
        self.piece.t0() / self.scale
    }

    /// Where it ends, in world distance.
    #[inline]
    fn t1(&self) -> f64 {
        self.piece.t1() / self.scale
    }
}

/// [`Piece::cubics`] as a task of the memo.
struct Cubics<'p, P>(&'p P, f64);

impl<P: Piece> LeTask for Cubics<'_, P> {
    type Out = PieceCubics;
    #[inline]
    fn run(self, le: &impl Fn(f32, f32) -> Rgb) -> PieceCubics {
        self.0.cubics(le, self.1)
    }
}

/// The pieces of [`Volumes`] along a ray (see the module docs). Each piece spans from the
/// last cut to the nearest end of a volume's current piece or start of a volume not yet
/// entered; a stretch that no volume covers is an empty piece.
pub struct OverlapSegments<'a, F: Field + 'a> {
    along: Along<'a, F>,
    streams: Vec<Stream<'a, F>>,
    /// Where the next piece starts.
    t: f64,
    /// Voxel steps of the streams already done.
    done_steps: u64,
}

/// What a walk of several volumes reads: the volumes, each one's scattering class, and
/// the index of their world boxes.
pub(super) struct Along<'a, F: Field> {
    pub(super) members: &'a [Member<F>],
    pub(super) class_of: &'a [Option<usize>],
    pub(super) index: &'a BoundsIndex,
}

impl<F: Field> Clone for Along<'_, F> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<F: Field> Copy for Along<'_, F> {}

impl<'a, F: Field + Send + 'a> OverlapSegments<'a, F> {
    pub(super) fn new(along: Along<'a, F>, ray: &Ray, t_min: f64, t_max: f64) -> Self {
        let mut streams = Vec::new();
        let mut done_steps = 0;
        let mut met = Vec::new();
        along.index.on_ray(ray, t_min, t_max, &mut met);
        for member in met {
            let m = &along.members[member];
            let (base, scale) = match &m.instance {
                Some(i) => {
                    let b = i.ray(ray);
                    (b.ray, b.scale)
                }
                None => (*ray, 1.0),
            };
            let mut pieces = m.field.segments(&base, t_min * scale, t_max * scale);
            match pieces.next() {
                Some(piece) => {
                    let memo = EmissionMemo::new(&m.medium.emission);
                    streams.push(Stream { member, pieces, piece, scale, memo });
                }
                None => done_steps += pieces.voxel_steps(),
            }
        }
        let t = streams.iter().map(Stream::t0).fold(f64::INFINITY, f64::min);
        OverlapSegments { along, streams, t, done_steps }
    }
}

impl<'a, F: Field + 'a> Iterator for OverlapSegments<'a, F> {
    type Item = OverlapPiece;

    fn next(&mut self) -> Option<OverlapPiece> {
        if self.streams.is_empty() {
            return None;
        }
        let t = self.t;
        // The next cut: the nearest end of a current piece, or start of a later one
        let end = self
            .streams
            .iter()
            .map(|s| if s.t0() > t { s.t0() } else { s.t1() })
            .fold(f64::INFINITY, f64::min);
        let mut piece = OverlapPiece::empty(t, end);
        let along = self.along;
        for s in self.streams.iter().filter(|s| s.t0() <= t) {
            let offset = ((t - s.t0()) * s.scale).max(0.0);
            let mut cubics = s.memo.run(Cubics(&s.piece, offset));
            if s.scale != 1.0 {
                cubics.density = to_world(cubics.density, s.scale);
                cubics.emission = cubics.emission.map(|c| to_world(c, s.scale));
            }
            let m = &along.members[s.member];
            piece.add(&cubics, m.medium.sigma_t, along.class_of[s.member]);
        }
        // Streams whose piece ends here move on; those that run out are done
        let mut i = 0;
        while i < self.streams.len() {
            let s = &mut self.streams[i];
            if s.t0() <= t && s.t1() <= end {
                if let Some(next) = s.pieces.next() {
                    s.piece = next;
                } else {
                    self.done_steps += s.pieces.voxel_steps();
                    self.streams.remove(i);
                    continue;
                }
            }
            i += 1;
        }
        self.t = end;
        Some(piece)
    }
}

impl<'a, F: Field + 'a> SegmentIter for OverlapSegments<'a, F> {
    fn voxel_steps(&self) -> u64 {
        self.done_steps + self.streams.iter().map(|s| s.pieces.voxel_steps()).sum::<u64>()
    }
}
