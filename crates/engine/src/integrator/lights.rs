//! The lights of a scene as the path integrator samples them: which next event technique
//! runs at scattering vertices ([`LightSampling`]), how its MIS weights are formed
//! ([`MisHeuristic`]), and the structures each technique draws from ([`Lights`]: classic
//! NEE's emitter table, FNEE's proxy, lights besides the volume), built once per scene.
//! The estimators that use them are in `integrator::volpath` (its module docs give the
//! weights).

use crate::light::external::ExternalLights;
use crate::light::mixture::{ProxyMixture, VolumeProxy};
use crate::light::nee::EmitterDistribution;
use crate::light::nee_mixture::{EmitterMixture, VolumeEmitters};
pub use plume_scene::sets::{LightSampling, MisHeuristic};
use plume_scene::NeeTable;
use plume_volume::proxy::ProxyGrid;
use plume_volume::Field;

/// The lights of a scene and their sampling structures (built once, immutable).
#[derive(Debug, Default)]
pub struct Lights {
    /// Full-resolution emitter distribution for classic NEE.
    pub nee: Option<EmitterDistribution>,
    /// Classic NEE over several volumes (`light::nee_mixture`), in place of `nee`.
    pub nee_several: Option<EmitterMixture>,
    /// FNEE proxy grid.
    pub proxy: Option<ProxyGrid>,
    /// FNEE over several volumes (`light::mixture`), in place of `proxy`.
    pub proxies: Option<ProxyMixture>,
    /// Lights besides the volume (`light::external`); `None` costs nothing.
    pub external: Option<ExternalLights>,
    /// How volume emission is split between AOV layers (`integrator::groups`).
    pub volume_layers: VolumeLayers,
}

impl Lights {
    /// Build what `light_sampling` needs over `volume`, with cell/voxel power = luminance
    /// of the emission density (`Y(L_e)`, METHOD §7). Nothing for `None`, or when nothing
    /// emits.
    ///
    /// # Errors
    /// An invalid proxy resolution (`--proxy-resolution`) or invalid emission power.
    pub fn build(
        volume: &plume_volume::Volume,
        emission: &crate::medium::Emission,
        light_sampling: LightSampling,
        proxy_resolution: u32,
    ) -> plume_core::error::Result<Lights> {
        Lights::build_with(volume, emission, light_sampling, proxy_resolution, NeeTable::Voxel)
    }

    /// [`Lights::build`] with classic NEE's table at the resolution `nee_table` asks for.
    ///
    /// # Errors
    /// As [`Lights::build`].
    pub fn build_with(
        volume: &plume_volume::Volume,
        emission: &crate::medium::Emission,
        light_sampling: LightSampling,
        proxy_resolution: u32,
        nee_table: NeeTable,
    ) -> plume_core::error::Result<Lights> {
        Ok(match light_sampling {
            LightSampling::None => Lights::default(),
            LightSampling::Nee => Lights {
                nee: EmitterDistribution::build_as(
                    volume,
                    crate::light::power::LightPower::new(emission),
                    nee_table,
                )?,
                ..Lights::default()
            },
            LightSampling::Fnee => Lights {
                proxy: ProxyGrid::build(volume, proxy_resolution, light_power(emission))?,
                ..Lights::default()
            },
        })
    }
}

impl Lights {
    /// The proxy FNEE samples the volume's emission through, if any: one volume's, or
    /// several volumes' mixture.
    #[inline]
    #[must_use]
    pub fn volume_proxy(&self) -> Option<VolumeProxy<'_>> {
        match (&self.proxy, &self.proxies) {
            (Some(p), _) => Some(VolumeProxy::One(p)),
            (None, Some(m)) => Some(VolumeProxy::Several(m)),
            (None, None) => None,
        }
    }

    /// The emitters classic NEE samples, with the voxels `field` holds for them: one
    /// volume's table, or several volumes' mixture. `None` without a table, or where the
    /// field has no voxels.
    #[inline]
    #[must_use]
    pub fn volume_emitters<'a, F: Field>(&'a self, field: &'a F) -> Option<VolumeEmitters<'a, F>> {
        match (&self.nee, &self.nee_several) {
            (Some(table), _) => Some(VolumeEmitters::One { table, volume: field.voxels()? }),
            (None, Some(mixture)) => Some(VolumeEmitters::Several { mixture, field }),
            (None, None) => None,
        }
    }

    /// The same structures for a volume reconstructed by `interpolation`: NEE draws its
    /// points from the voxel's box or from the trilinear hat (`light/nee.rs`); FNEE's proxy
    /// only guides directions and stays as it is (METHOD.md §12).
    #[must_use]
    pub fn for_interpolation(self, interpolation: plume_volume::Interpolation) -> Lights {
        Lights { nee: self.nee.map(|n| n.for_interpolation(interpolation)), ..self }
    }
}

/// How volume emission goes to the AOV layers (`integrator::groups`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VolumeLayers {
    /// No volume has a light group: `emission` and `scattered`.
    #[default]
    Unsplit,
    /// One group holds every emitting volume: all of it to this layer (an index into the
    /// layout's groups).
    One(usize),
    /// Several groups: the field's views ([`plume_volume::Field::emission_groups`]) give
    /// each group's share; `ungrouped` when some emitting volume has no group, whose share
    /// is the rest.
    Split {
        /// Some emitting volume has no group.
        ungrouped: bool,
    },
}

/// Power that light sampling distributes by: the luminance `Y(L_e)` of the emission
/// density with unit `--emission-scale` and white `--emission-color`. The scale only
/// multiplies every voxel's power, and the tint is a mild reweighting that any valid pdf
/// absorbs, so leaving both out keeps the estimators unbiased while letting a brick cache
/// store the FNEE proxy's cell sums once for any scale or tint. Blackbody luminance is
/// tabulated (`light::power`).
pub fn light_power(emission: &crate::medium::Emission) -> impl Fn(f32, f32) -> f64 + Sync {
    let power = crate::light::power::LightPower::new(emission);
    move |d: f32, s: f32| power.power(d, s)
}

/// The weight `Φ_i` by which FNEE over several volumes chooses a volume's proxy
/// (`light::mixture`): its total power times the emission scale and the luminance of the
/// tint, which [`light_power`] leaves out.
#[must_use]
pub fn proxy_weight(proxy: &ProxyGrid, emission: &crate::medium::Emission) -> f64 {
    proxy.total_power() * f64::from(emission.scale) * f64::from(emission.color.luminance())
}
