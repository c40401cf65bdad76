//! Emission density `L_e(ρ, v)` from the density ρ and the stored *source* value v
//! (METHOD.md §2).
//!
//! | kind / convention | physical | cycles |
//! |---|---|---|
//! | blackbody (v = T′ in K) | `s_e · c · ρ · C(T′)` | `s_e · c · σ_SB/π · 10⁻⁶ · T′⁴ · Ĉ(T′)` |
//! | grid (v = grid value)   | `s_e · c · ρ · v`      | `s_e · c · v` |
//!
//! `C(T)` is full Planck integrated against the CIE 1931 matching functions into linear
//! Rec.709 (W m⁻² sr⁻¹), `Ĉ = C/Y` its luminance-normalised colour, `s_e` the
//! `--emission-scale`, `c` the `--emission-color`. The *cycles* convention reproduces
//! Blender's Principled Volume: emission is not multiplied by density.
//!
//! Temperatures are mapped (`kelvin` or `linear:OFFSET,SCALE`) and cut off (physical
//! blackbody only: `T′ < T_cut` emits nothing) once, when the volume is built, so that a
//! stored source of 0 always means "no emission" and the DDA can skip it.

pub use plume_scene::sets::{Convention, EmissionKind, TemperatureMap};
use std::cell::Cell;

use plume_core::color::blackbody::{blackbody_table, cycles_blackbody};
use plume_core::color::Rgb;

/// An emission model (see the module table).
#[derive(Clone, Copy, Debug)]
pub struct Emission {
    /// What drives emission.
    pub kind: EmissionKind,
    /// Physical or Cycles meaning.
    pub convention: Convention,
    /// `s_e`, the emission scale.
    pub scale: f32,
    /// `c`, the emission colour (a tint for blackbody).
    pub color: Rgb,
    /// Temperature mapping (blackbody only).
    pub temperature_map: TemperatureMap,
    /// Physical blackbody: temperatures below this emit nothing, in Kelvin.
    pub cutoff_kelvin: f32,
}

impl Emission {
    /// No emission at all.
    #[must_use]
    pub fn none() -> Emission {
        Emission {
            kind: EmissionKind::None,
            convention: Convention::Physical,
            scale: 0.0,
            color: Rgb::ONE,
            temperature_map: TemperatureMap::Kelvin,
            cutoff_kelvin: 0.0,
        }
    }

    /// A physical blackbody read from a temperature grid in Kelvin, times `scale`, dark
    /// below 500 K: what a scene's emission defaults to with a temperature grid.
    #[must_use]
    pub fn blackbody(scale: f32) -> Emission {
        Emission {
            kind: EmissionKind::Blackbody,
            convention: Convention::Physical,
            scale,
            color: Rgb::ONE,
            temperature_map: TemperatureMap::Kelvin,
            cutoff_kelvin: 500.0,
        }
    }

    /// Raw source-grid value → stored source (Kelvin after map and cutoff, or the grid
    /// value). 0 means "no emission"; negative or non-finite results are cleaned (and
    /// counted) by the volume builder.
    #[inline]
    #[must_use]
    pub fn map_source(&self, v: f32) -> f32 {
        match self.kind {
            EmissionKind::None => 0.0,
            EmissionKind::Grid => v,
            EmissionKind::Blackbody => {
                let t = self.temperature_map.kelvin(v);
                let cut = match self.convention {
                    Convention::Physical => self.cutoff_kelvin,
                    Convention::Cycles => 0.0,
                };
                if t.is_finite() && t < cut && t >= 0.0 {
                    0.0
                } else {
                    t
                }
            }
        }
    }

    /// What [`Emission::map_source`] depends on, as text: a brick cache stores sources
    /// mapped with one key and may only be rendered with the same.
    #[must_use]
    pub fn source_key(&self) -> String {
        match self.kind {
            EmissionKind::None => "none".into(),
            EmissionKind::Grid => "grid".into(),
            EmissionKind::Blackbody => {
                let cut = match self.convention {
                    Convention::Physical => self.cutoff_kelvin,
                    Convention::Cycles => 0.0,
                };
                format!("blackbody map={:?} cutoff={cut}K", self.temperature_map)
            }
        }
    }

    /// What light sampling's power (`integrator::light_power`) depends on: the source key
    /// and the convention (never the scale or tint).
    #[must_use]
    pub fn light_key(&self) -> String {
        format!("{} convention={:?}", self.source_key(), self.convention)
    }

    /// Emission density `L_e` for density `density` and stored source `source`.
    #[inline]
    #[must_use]
    pub fn le(&self, density: f32, source: f32) -> Rgb {
        if source == 0.0 {
            return Rgb::ZERO;
        }
        match self.kind {
            EmissionKind::None => Rgb::ZERO,
            EmissionKind::Blackbody => self.blackbody_with(self.blackbody_of(source), density),
            EmissionKind::Grid => match self.convention {
                Convention::Physical => self.color * (self.scale * source * density),
                Convention::Cycles => self.color * (self.scale * source),
            },
        }
    }

    /// The part of a blackbody's `L_e` that depends on the temperature alone: `c · C(T′)`
    /// (physical) or all of it, `s_e · c · σ_SB/π · 10⁻⁶ · T′⁴ · Ĉ(T′)` (cycles).
    #[inline]
    fn blackbody_of(&self, source: f32) -> Rgb {
        match self.convention {
            Convention::Physical => blackbody_table().rgb(source) * self.color,
            Convention::Cycles => cycles_blackbody(source) * self.color * self.scale,
        }
    }

    /// A blackbody's `L_e` from [`Emission::blackbody_of`] and the density: times `s_e ρ`
    /// (physical), as it is (cycles).
    #[inline]
    fn blackbody_with(&self, of_temperature: Rgb, density: f32) -> Rgb {
        match self.convention {
            Convention::Physical => of_temperature * (self.scale * density),
            Convention::Cycles => of_temperature,
        }
    }

    /// True when `self` and `other` give the same `le` for every input: every field equal
    /// bit for bit (so a NaN parameter matches only itself).
    #[must_use]
    pub fn same_as(&self, other: &Emission) -> bool {
        let bits = |e: &Emission| {
            let map = match e.temperature_map {
                TemperatureMap::Kelvin => [0, 0],
                TemperatureMap::Linear { offset, scale } => [offset.to_bits(), scale.to_bits()],
            };
            (
                e.kind,
                e.convention,
                e.scale.to_bits(),
                e.color.0.map(f32::to_bits),
                matches!(e.temperature_map, TemperatureMap::Kelvin),
                map,
                e.cutoff_kelvin.to_bits(),
            )
        };
        bits(self) == bits(other)
    }

    /// True when emission can be non-zero where density is zero (then the point
    /// estimator, which scores only at collisions, misses it).
    #[must_use]
    pub fn emits_without_density(&self) -> bool {
        self.kind != EmissionKind::None && self.convention == Convention::Cycles
    }
}

/// Slots of each thread's [`EmissionMemo`] table (a power of two): 16384 × 24 bytes,
/// which L2 holds; smaller tables save markedly less of a render's time, a larger one
/// hardly more (docs/BENCHMARKS.md, "Interpolation: trilinear vs nearest"). The table is
/// static thread-local storage: 384 KiB of every thread's stack allocation (glibc places
/// it there), far below the 2 MiB of a Rust or rayon thread.
const MEMO_SLOTS: usize = 16384;

/// One slot of the thread's memo table: the key (the tag of the emission model the value
/// was computed for, above the bits of the temperature; tag 0, never handed out, marks an
/// empty slot) and the value, [`Emission::blackbody_of`] that temperature.
#[derive(Clone, Copy, Debug)]
struct MemoEntry {
    key: u64,
    value: Rgb,
}

/// The thread's memo table, all zero at first (so it costs no space in the binary).
struct MemoTable {
    /// The last tag handed out.
    last_tag: Cell<u32>,
    entries: [Cell<MemoEntry>; MEMO_SLOTS],
}

thread_local! {
    /// One table per thread, kept across rays: consecutive samples of a pixel cross the
    /// same voxels, so most corners a ray needs were evaluated by the previous ray.
    static MEMO: MemoTable = const {
        MemoTable { last_tag: Cell::new(0), entries: [const { Cell::new(MemoEntry { key: 0, value: Rgb::ZERO }) }; MEMO_SLOTS] }
    };

    /// The model the thread's current tag stands for, and that tag (apart from [`MEMO`],
    /// which stays all zero).
    static CURRENT: Cell<Option<(Emission, u32)>> = const { Cell::new(None) };
}

/// [`Emission::le`] with a direct-mapped memo of the blackbody of the temperatures asked
/// for, one table per thread kept from ray to ray.
///
/// Along a ray, consecutive trilinear pieces share 4 of their 8 corner voxels, and every
/// emitting piece needs `le` of each corner (`volume/trilinear/piece.rs`); the next sample
/// of the same pixel (samples are taken pixel by pixel) crosses nearly the same voxels.
/// The memo answers those without evaluating the blackbody again. It keeps the part of
/// `L_e` that depends on the temperature alone ([`Emission::blackbody_of`]; the density
/// factor is one multiplication, done as `le` does it), keyed by the exact bits of the
/// temperature and the tag of the emission model (a new tag whenever a memo is made for a
/// model other than the thread's last one). So a hit returns exactly what `le` would, bit
/// for bit, and images do not depend on what the thread rendered before. Grid emission,
/// a product or two, is not memoized.
#[derive(Debug)]
pub(crate) struct EmissionMemo<'e> {
    emission: &'e Emission,
    tag: u32,
    /// This thread's [`MEMO`], found once: a lookup through `MEMO.with` is a call the
    /// compiler may keep out of line in every walk that asks (whether it does can change
    /// with unrelated code, and out of line it costs a scattering render a sizeable share
    /// of its instructions). A raw pointer keeps the memo on its thread: it is neither
    /// `Send` nor `Sync`.
    table: *const MemoTable,
}

impl<'e> EmissionMemo<'e> {
    /// A memo of `emission.le` on this thread's table.
    pub(crate) fn new(emission: &'e Emission) -> Self {
        let tag = MEMO.with(|table| match CURRENT.get() {
            Some((model, tag)) if model.same_as(emission) => tag,
            _ => {
                let tag = table.last_tag.get().wrapping_add(1);
                if tag == 0 {
                    // Tags wrapped: no entry may keep an old tag that could come back
                    table
                        .entries
                        .iter()
                        .for_each(|e| e.set(MemoEntry { key: 0, value: Rgb::ZERO }));
                }
                let tag = tag.max(1);
                table.last_tag.set(tag);
                CURRENT.set(Some((*emission, tag)));
                tag
            }
        });
        EmissionMemo { emission, tag, table: MEMO.with(std::ptr::from_ref) }
    }

    /// `emission.le(density, source)`: a blackbody's temperature part from the memo.
    #[inline]
    pub(crate) fn le(&self, density: f32, source: f32) -> Rgb {
        if source == 0.0 || self.emission.kind != EmissionKind::Blackbody {
            // A grid's emission is a product or two, cheaper than a lookup
            return self.emission.le(density, source);
        }
        self.emission.blackbody_with(self.of_temperature(source), density)
    }

    /// [`Emission::blackbody_of`] `source` (not 0), from the memo.
    #[inline]
    fn of_temperature(&self, source: f32) -> Rgb {
        let bits = source.to_bits();
        let key = (u64::from(self.tag) << 32) | u64::from(bits);
        // Fibonacci hashing: the top bits of the product pick the slot
        let slot = (bits.wrapping_mul(0x9e37_79b1) >> (32 - MEMO_SLOTS.trailing_zeros())) as usize;
        // SAFETY: `table` is this thread's `MEMO` (taken in `new` on this thread; the raw
        // pointer keeps `self` from leaving it), which lives as long as the thread, so as
        // long as `self`; it is only read and written through `Cell`s
        let table = unsafe { &*self.table };
        let entry = table.entries[slot].get();
        if entry.key == key {
            return entry.value;
        }
        let value = self.emission.blackbody_of(source);
        table.entries[slot].set(MemoEntry { key, value });
        value
    }

    /// Runs `task` with [`EmissionMemo::le`] made for the model's kind and convention:
    /// the same values bit for bit, without deciding on them at every corner (a trilinear
    /// piece asks 8 times, a render millions of times).
    #[inline]
    pub(crate) fn run<T: LeTask>(&self, task: T) -> T::Out {
        match (self.emission.kind, self.emission.convention) {
            (EmissionKind::Blackbody, Convention::Cycles) => task.run(&|_: f32, source: f32| {
                if source == 0.0 {
                    Rgb::ZERO
                } else {
                    self.of_temperature(source)
                }
            }),
            (EmissionKind::Blackbody, Convention::Physical) => {
                let scale = self.emission.scale;
                task.run(&|density: f32, source: f32| {
                    if source == 0.0 {
                        Rgb::ZERO
                    } else {
                        self.of_temperature(source) * (scale * density)
                    }
                })
            }
            _ => task.run(&|density: f32, source: f32| self.emission.le(density, source)),
        }
    }
}

/// Work that reads `L_e` voxel by voxel through the function it is given
/// ([`EmissionMemo::run`]).
pub(crate) trait LeTask {
    /// What the work gives.
    type Out;
    /// Does the work with `le(density, source)`.
    fn run(self, le: &impl Fn(f32, f32) -> Rgb) -> Self::Out;
}

#[cfg(test)]
mod tests {
    use super::*;
    use plume_core::sampling::Sampler;

    /// The memo returns exactly `le`, bit for bit, however keys collide in its slots:
    /// 200 000 lookups drawn from 3 × [`MEMO_SLOTS`] distinct temperatures (so entries are
    /// evicted and refilled), each with a density drawn afresh (the memo keeps the
    /// temperature's part and applies the density after), in both conventions and for
    /// grid emission; a memo that returned a stale value would fail, since no two
    /// temperatures share an emission.
    #[test]
    fn the_memo_returns_exactly_what_le_returns() {
        for (kind, convention) in [
            (EmissionKind::Blackbody, Convention::Cycles),
            (EmissionKind::Blackbody, Convention::Physical),
            (EmissionKind::Grid, Convention::Physical),
        ] {
            let emission = Emission {
                kind,
                convention,
                scale: 1.5,
                color: Rgb([1.0, 0.8, 0.6]),
                temperature_map: TemperatureMap::Kelvin,
                cutoff_kelvin: 0.0,
            };
            let mut rng = Sampler::new(3, 0, 0);
            let temperatures: Vec<f32> =
                (0..3 * MEMO_SLOTS).map(|i| 900.0 + 0.37 * i as f32).collect();
            let memo = EmissionMemo::new(&emission);
            for _ in 0..200_000 {
                let (d, s) = (
                    0.1 + rng.next_f32(),
                    temperatures[(rng.next_u64() % temperatures.len() as u64) as usize],
                );
                let (a, b) = (memo.le(d, s), emission.le(d, s));
                assert_eq!(
                    a.0.map(f32::to_bits),
                    b.0.map(f32::to_bits),
                    "{kind:?} {convention:?}: density {d}, source {s}"
                );
            }
            assert_eq!(memo.le(0.5, 0.0).0, [0.0; 3]);
        }
    }

    /// [`EmissionMemo::run`] hands its task an `le` giving exactly `le`'s bits, for every
    /// kind and convention, a scale other than 1 and sources of 0.
    #[test]
    fn a_memo_task_reads_exactly_what_le_returns() {
        /// Evaluates `le` over a list of voxels.
        struct Each<'v>(&'v [(f32, f32)]);
        impl LeTask for Each<'_> {
            type Out = Vec<Rgb>;
            fn run(self, le: &impl Fn(f32, f32) -> Rgb) -> Vec<Rgb> {
                self.0.iter().map(|&(d, s)| le(d, s)).collect()
            }
        }
        let mut rng = Sampler::new(4, 0, 0);
        let voxels: Vec<(f32, f32)> = (0..5000)
            .map(|i| {
                (
                    0.1 + 3.0 * rng.next_f32(),
                    if i % 7 == 0 { 0.0 } else { 500.0 + 9000.0 * rng.next_f32() },
                )
            })
            .collect();
        for kind in [EmissionKind::Blackbody, EmissionKind::Grid, EmissionKind::None] {
            for convention in [Convention::Cycles, Convention::Physical] {
                let emission = Emission {
                    kind,
                    convention,
                    scale: 1.7,
                    color: Rgb([1.0, 0.8, 0.6]),
                    temperature_map: TemperatureMap::Kelvin,
                    cutoff_kelvin: 0.0,
                };
                let memo = EmissionMemo::new(&emission);
                // Twice: the first pass fills the memo, the second reads it
                for _ in 0..2 {
                    for (&(d, s), got) in voxels.iter().zip(memo.run(Each(&voxels))) {
                        assert_eq!(
                            got.0.map(f32::to_bits),
                            emission.le(d, s).0.map(f32::to_bits),
                            "{kind:?} {convention:?}: density {d}, source {s}"
                        );
                    }
                }
            }
        }
    }

    /// The thread's table is shared by every memo on the thread, and kept from ray to
    /// ray: memos of two models used in turn on the same voxels each return their own
    /// model's `le` (a table keyed on the voxel alone would hand one model's values to the
    /// other), and a memo made again for a model finds the values of the first.
    #[test]
    fn memos_of_different_models_on_one_thread_stay_apart() {
        let model = |convention, scale| Emission {
            kind: EmissionKind::Blackbody,
            convention,
            scale,
            color: Rgb::ONE,
            temperature_map: TemperatureMap::Kelvin,
            cutoff_kelvin: 0.0,
        };
        let models = [
            model(Convention::Cycles, 1.0),
            model(Convention::Physical, 1.0),
            model(Convention::Physical, 2.0),
        ];
        assert!(models[0].same_as(&models[0]) && !models[1].same_as(&models[2]));
        let voxels: Vec<(f32, f32)> =
            (0..64).map(|i| (0.25 + 0.01 * i as f32, 1000.0 + 37.0 * i as f32)).collect();
        for round in 0..3 {
            for model in &models {
                let memo = EmissionMemo::new(model);
                for &(d, s) in &voxels {
                    assert_eq!(
                        memo.le(d, s).0.map(f32::to_bits),
                        model.le(d, s).0.map(f32::to_bits),
                        "round {round}, {model:?}, voxel ({d}, {s})"
                    );
                }
            }
        }
    }
}
