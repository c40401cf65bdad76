//! AOVs (`--aovs`): the beauty split by where its light came from, written as layers of
//! the same EXR.
//!
//! Every contribution the integrator adds to a sample's radiance belongs to exactly one
//! [`Component`]:
//! - `emission`: the volume's emission reaching the camera directly (the camera
//!   segment's line integral);
//! - `scattered`: the volume's emission after one or more scattering events (forward
//!   segments after a collision, NEE and FNEE);
//! - one layer per light group: an external light's radiance, seen directly or after
//!   scattering (lights are grouped by their `group` key; by default one group per kind:
//!   `sun`, `sphere`, `environment`, `sky`), and the emission of volumes with a `group`,
//!   which then leaves `emission` and `scattered` (`integrator::groups`).
//!
//! So the colour layers sum to the beauty: per sample exactly (each contribution is added
//! to both), per pixel up to the rounding of each layer's fixed-point sum and of `f32`.
//! Besides the colour layers: `alpha` (the beauty's alpha) and `depth`, the **expected
//! distance to the first collision of camera rays that collide**: each camera sample that
//! samples a collision along its ray adds its distance `t` and a hit, and the pixel's
//! depth is `Σ t / Σ hits` (the mean of the free-path law's conditional distance: a
//! ratio estimator, consistent; 0 where no sample collided). Collisions are drawn from
//! the exact free-path law for every estimator (ray-march draws one for the layer with
//! the camera segment's own number, which changes nothing else), so the depth does not
//! depend on `--method`.
//!
//! With `--denoise` the layout also has the **half sums** (`half.R`, `half.G`, `half.B`,
//! `half.A`, `half.n`): the beauty and count of the samples that [`crate::denoise::half_of`]
//! puts in the second half buffer. They are summed like every channel, so sums files and
//! merges carry them, and the first half is the total minus them; they are not a layer.
//! When the denoiser leaves the camera segment's emission out of the filter
//! ([`Filtered::LessEmission`]), the colour half sums hold the beauty less that emission
//! and are named `half.rest.R`, `half.rest.G`, `half.rest.B`, so a sums file says which.
//!
//! Without `--aovs` or `--denoise` the integrator is instantiated with [`NoAovs`], whose
//! methods are empty: it compiles to the code of an integrator without AOVs.

pub use plume_scene::Filtered;

/// Where a contribution's light came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    /// Volume emission seen directly.
    Emission,
    /// Volume emission after scattering.
    Scattered,
    /// An external light of this group (index into [`AovLayout::groups`]).
    Light(usize),
}

/// Receives a sample's contributions by component.
pub trait Aovs {
    /// Whether anything is recorded (lets the integrator skip work for [`NoAovs`]).
    const ON: bool;
    /// Whether volume emission is split between light-group layers
    /// (`integrator::groups`); only the render's own AOVs do.
    const GROUPS: bool = false;
    /// `w · e` was added to the beauty for `component`.
    fn add(&mut self, component: Component, w: [f64; 3], e: [f64; 3]);
    /// The camera ray's first collision is at distance `t`.
    fn first_collision(&mut self, t: f64);
    /// Start a new sample.
    fn begin(&mut self);
    /// The sample's channel values (`AovLayout::channels`).
    fn values(&self) -> &[f64];
    /// The sample's beauty `l` goes to the second half buffer: the half sums' channels
    /// ([`AovLayout::half_at`]; less the sample's emission with [`Filtered::LessEmission`]).
    fn half(&mut self, l: [f64; 4]);
}

/// No AOVs: records nothing, costs nothing.
pub struct NoAovs;

impl Aovs for NoAovs {
    const ON: bool = false;
    #[inline(always)]
    fn add(&mut self, _component: Component, _w: [f64; 3], _e: [f64; 3]) {}
    #[inline(always)]
    fn first_collision(&mut self, _t: f64) {}
    #[inline(always)]
    fn begin(&mut self) {}
    #[inline(always)]
    fn values(&self) -> &[f64] {
        &[]
    }
    #[inline(always)]
    fn half(&mut self, _l: [f64; 4]) {}
}

/// Names of the fixed colour layers.
pub const FIXED_LAYERS: [&str; 2] = ["emission", "scattered"];

pub use plume_scene::lights::RESERVED;

/// Names of the half sums' channels (`--denoise`), after the layers' channels.
pub const HALF_CHANNELS: [&str; crate::film::HALF_CHANNEL_COUNT] =
    ["half.R", "half.G", "half.B", "half.A", "half.n"];

/// Names of the half sums' channels when the camera emission is not filtered
/// ([`Filtered::LessEmission`]): the colour is the beauty less that emission.
pub const REST_HALF_CHANNELS: [&str; crate::film::HALF_CHANNEL_COUNT] =
    ["half.rest.R", "half.rest.G", "half.rest.B", "half.A", "half.n"];

/// The AOV channels of a render: the fixed colour layers, one colour layer per light
/// group, depth's two sums, and with `--denoise` the half sums.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AovLayout {
    /// Light groups, in the order of their layers.
    pub groups: Vec<String>,
    /// Whether the half sums follow the layers' channels (`--denoise`), and what the
    /// denoiser filters (which their colour channels hold).
    pub halves: Option<Filtered>,
}

impl AovLayout {
    /// Channels of the layers: 3 per colour layer, then depth's `Σ t` and `Σ hits`.
    #[must_use]
    pub fn layer_channels(&self) -> usize {
        3 * (FIXED_LAYERS.len() + self.groups.len()) + 2
    }

    /// Number of summed channels per pixel: the layers', then the half sums if any.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.layer_channels() + if self.halves.is_some() { HALF_CHANNELS.len() } else { 0 }
    }

    /// The first of the half sums' channels, if the layout has them.
    #[must_use]
    pub fn half_at(&self) -> Option<usize> {
        self.halves.map(|_| self.layer_channels())
    }

    /// The channels' names, in sum order: `emission.R`, …, `<group>.B`, `depth.Z`,
    /// `depth.hits`.
    #[must_use]
    pub fn channel_names(&self) -> Vec<String> {
        let mut names = Vec::with_capacity(self.channels());
        for layer in FIXED_LAYERS.iter().copied().chain(self.groups.iter().map(String::as_str)) {
            for c in ["R", "G", "B"] {
                names.push(format!("{layer}.{c}"));
            }
        }
        names.push("depth.Z".into());
        names.push("depth.hits".into());
        match self.halves {
            Some(Filtered::Beauty) => names.extend(HALF_CHANNELS.iter().map(|c| (*c).to_string())),
            Some(Filtered::LessEmission) => {
                names.extend(REST_HALF_CHANNELS.iter().map(|c| (*c).to_string()))
            }
            None => {}
        }
        names
    }

    /// The layout whose [`AovLayout::channel_names`] are `names`, if they are one.
    #[must_use]
    pub fn from_channel_names(names: &[String]) -> Option<AovLayout> {
        let has_halves = names.last().is_some_and(|c| c == HALF_CHANNELS[HALF_CHANNELS.len() - 1]);
        let n = names.len() - if has_halves { HALF_CHANNELS.len().min(names.len()) } else { 0 };
        let rest = names.get(n).is_some_and(|c| c == REST_HALF_CHANNELS[0]);
        let halves =
            has_halves.then_some(if rest { Filtered::LessEmission } else { Filtered::Beauty });
        if n < 8 || (n - 2) % 3 != 0 {
            return None;
        }
        let groups: Vec<String> = names[6..n - 2]
            .chunks(3)
            .map(|c| c[0].strip_suffix(".R").unwrap_or("").to_string())
            .collect();
        let layout = AovLayout { groups, halves };
        (layout.channel_names() == names).then_some(layout)
    }

    /// The offset of `component`'s red channel.
    #[inline]
    pub(crate) fn offset(component: Component) -> usize {
        match component {
            Component::Emission => 0,
            Component::Scattered => 3,
            Component::Light(g) => 6 + 3 * g,
        }
    }

    /// Per-pixel layer values from the channel sums of one pixel: colours `Σ / spp`,
    /// depth `Σ t / Σ hits` (the half sums are not a layer). `value(sum, n)` divides a sum
    /// by a count.
    pub fn pixel(&self, sums: &[i128], spp: u64, value: impl Fn(i128, u64) -> f32) -> Vec<f32> {
        let n = self.layer_channels();
        let mut out: Vec<f32> = sums[..n - 2].iter().map(|&s| value(s, spp)).collect();
        let hits = crate::film::count(sums[n - 1]);
        out.push(if hits == 0 { 0.0 } else { value(sums[n - 2], hits) });
        out
    }
}

/// One sample's AOV values (reused across samples).
#[derive(Clone, Debug)]
pub struct AovSample {
    /// The channels of [`AovLayout::channels`].
    pub values: Vec<f64>,
    /// Where depth's two sums are: the last two of the layers' channels.
    depth_at: usize,
    /// Whether the half sums' colour is the beauty less the sample's emission.
    rest: bool,
}

impl AovSample {
    /// Zeroed values for `channels` channels (`AovLayout::channels`), with the half sums
    /// from channel `at` if any ([`AovLayout::half_at`]), holding what `filtered` says.
    #[must_use]
    pub fn new(channels: usize, half: Option<(usize, Filtered)>) -> AovSample {
        let depth_at = half.map_or(channels, |(at, _)| at) - 2;
        AovSample {
            values: vec![0.0; channels],
            depth_at,
            rest: half.is_some_and(|(_, f)| f == Filtered::LessEmission),
        }
    }
}

impl Aovs for AovSample {
    const ON: bool = true;
    const GROUPS: bool = true;
    #[inline]
    fn add(&mut self, component: Component, w: [f64; 3], e: [f64; 3]) {
        let o = AovLayout::offset(component);
        for ((a, v), w) in self.values[o..o + 3].iter_mut().zip(e).zip(w) {
            *a += w * v;
        }
    }

    fn first_collision(&mut self, t: f64) {
        self.values[self.depth_at] = t;
        self.values[self.depth_at + 1] = 1.0;
    }

    fn begin(&mut self) {
        self.values.fill(0.0);
    }

    fn values(&self) -> &[f64] {
        &self.values
    }

    fn half(&mut self, mut l: [f64; 4]) {
        // The half sums follow depth's two sums (`AovLayout::half_at`)
        let at = self.depth_at + 2;
        if self.rest {
            let o = AovLayout::offset(Component::Emission);
            for (v, e) in l.iter_mut().zip(&self.values[o..o + 3]) {
                *v -= e;
            }
        }
        self.values[at..at + 4].copy_from_slice(&l);
        self.values[at + 4] = 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A layout's channel names read back as that layout, for each kind of half sums; the
    /// names say what the half sums hold.
    #[test]
    fn channel_names_round_trip_and_name_what_the_halves_hold() {
        for halves in [None, Some(Filtered::Beauty), Some(Filtered::LessEmission)] {
            let layout = AovLayout { groups: vec!["sun".into()], halves };
            let names = layout.channel_names();
            assert_eq!(AovLayout::from_channel_names(&names), Some(layout.clone()), "{names:?}");
            assert_eq!(
                names.iter().any(|n| n == "half.rest.R"),
                halves == Some(Filtered::LessEmission),
                "{names:?}"
            );
        }
    }

    /// With [`Filtered::LessEmission`] the half sums hold the beauty less the sample's
    /// camera emission (alpha and the count as they are); with [`Filtered::Beauty`] the
    /// beauty.
    #[test]
    fn rest_half_sums_leave_out_the_samples_emission() {
        for (filtered, want) in [
            (Filtered::Beauty, [3.0, 5.0, 7.0, 0.5, 1.0]),
            (Filtered::LessEmission, [2.0, 3.0, 4.0, 0.5, 1.0]),
        ] {
            let layout = AovLayout { groups: vec![], halves: Some(filtered) };
            let at = layout.half_at().unwrap();
            let mut a = AovSample::new(layout.channels(), Some((at, filtered)));
            a.begin();
            a.add(Component::Emission, [1.0; 3], [1.0, 2.0, 3.0]);
            a.add(Component::Scattered, [0.5; 3], [4.0, 6.0, 8.0]);
            a.half([3.0, 5.0, 7.0, 0.5]);
            assert_eq!(&a.values()[at..at + 5], &want, "{filtered:?}");
        }
    }
}
