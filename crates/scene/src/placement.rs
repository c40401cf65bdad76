//! Where a volume sits in the world: a transform applied after the file's own
//! (`world = M · world_file`), given as `translate`, `rotate` and `scale`, or as a 4×4
//! `matrix`.
//!
//! `translate`, `rotate`, `scale` compose as Blender's object matrix does:
//! `M = T · R · S`, scale first, then the rotation, then the translation, with `rotate` the
//! XYZ Euler angles in degrees (Blender's default rotation mode: about x first, then y,
//! then z, all about the world axes, so `R = R_z · R_y · R_x`). `matrix` is the whole
//! affine map, rows as written (`[[a, b, c, tx], [d, e, f, ty], [g, h, i, tz],
//! [0, 0, 0, 1]]`, translation in the last column), as Blender prints `matrix_world`.
//!
//! **Instances** (`instances = [{ translate = [2, 0, 0] }, …]`) are placements too, each
//! applied after the volume's own: an instance's whole placement is
//! `M_instance · M` ([`instance_placement`]).
//!
//! **Coefficients under a placement** ([`VolumeSpace`]): per world unit by default, so a
//! volume scaled by 2 is twice as deep; or, as Cycles has it for volume objects whose
//! render space is *Object* (Blender's default), divided by the placement's scale
//! `s = |L (1, 1, 1)/√3|` (`L` its linear part), extinction and emission alike, so that
//! scaling keeps the volume's look.

use glam::{DAffine3, DMat3, DVec3};
use serde::{Deserialize, Serialize};

use plume_core::choice;
use plume_core::error::{Error, Result};

/// Which length the volume's coefficients are per, once it is placed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VolumeSpace {
    /// Per world unit: the placement changes where the volume is, not its coefficients.
    #[default]
    World,
    /// Per object unit, as Cycles' *Object* render space: extinction and emission are
    /// divided by the placement's scale `|L (1, 1, 1)/√3|`.
    Object,
}

choice!(VolumeSpace {
    "world" => VolumeSpace::World, "Coefficients per world unit: a volume scaled by 2 is twice as deep";
    "object" => VolumeSpace::Object, "Cycles' Object space (Blender's default): extinction and emission divided by the placement's scale, so scaling keeps the look";
});

impl VolumeSpace {
    /// What extinction and emission are multiplied by under the placement `xf`: 1 in
    /// world space; `1 / |L (1, 1, 1)/√3|` in object space (Cycles' `object_volume_density`).
    #[must_use]
    pub fn coefficient_factor(self, xf: DAffine3) -> f64 {
        match self {
            VolumeSpace::World => 1.0,
            VolumeSpace::Object => 1.0 / (xf.matrix3 * DVec3::ONE.normalize()).length(),
        }
    }
}

/// A scale: one factor for every axis, or one per axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Scale {
    /// The same factor on every axis.
    Uniform(f64),
    /// x, y, z.
    Axes([f64; 3]),
}

impl<'de> Deserialize<'de> for Scale {
    /// A number or three; anything else is refused with what is expected.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Scale, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Uniform(f64),
            Axes([f64; 3]),
        }
        match Raw::deserialize(d) {
            Ok(Raw::Uniform(s)) => Ok(Scale::Uniform(s)),
            Ok(Raw::Axes(s)) => Ok(Scale::Axes(s)),
            Err(_) => Err(serde::de::Error::custom("expected a number or [x, y, z]")),
        }
    }
}

impl Scale {
    /// Per axis.
    #[must_use]
    pub fn axes(self) -> DVec3 {
        match self {
            Scale::Uniform(s) => DVec3::splat(s),
            Scale::Axes(s) => DVec3::from_array(s),
        }
    }
}

impl std::str::FromStr for Scale {
    type Err = String;

    /// `2` or `1,2,0.5`.
    fn from_str(s: &str) -> std::result::Result<Scale, String> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let num =
            |t: &str| t.parse::<f64>().map_err(|_| format!("{s:?}: expected a number or x,y,z"));
        match parts.as_slice() {
            [a] => Ok(Scale::Uniform(num(a)?)),
            [x, y, z] => Ok(Scale::Axes([num(x)?, num(y)?, num(z)?])),
            _ => Err(format!("{s:?}: expected a number or x,y,z")),
        }
    }
}

/// A volume's placement as the scene gives it (the `[volume]` keys of the same names), and
/// as a scene file writes one instance of a volume (an inline table of those keys in
/// `instances`, `volumes::VolumeInput::instances`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Placement {
    /// Translation, world units.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translate: Option<[f64; 3]>,
    /// XYZ Euler angles, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotate: Option<[f64; 3]>,
    /// Scale factors.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// The whole affine map, rows as written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[[f64; 4]; 4]>,
}

impl Placement {
    /// The transform `M` of `world = M · world_file`, or `None` where nothing is given
    /// (the file's own placement, exactly as before).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the key (`{prefix}.matrix`, `{prefix}.scale`, …)
    /// for a value that is not finite, a matrix beside `translate`, `rotate` or `scale`, a
    /// last row other than `[0, 0, 0, 1]`, or a singular transform.
    pub fn transform(&self, prefix: &str) -> Result<Option<DAffine3>> {
        let key = |k: &str| format!("{prefix}.{k}");
        let finite = |k: &str, v: &[f64]| -> Result<()> {
            match v.iter().find(|x| !x.is_finite()) {
                Some(x) => Err(Error::invalid(&key(k), format!("{x} is not finite"))),
                None => Ok(()),
            }
        };
        if let Some(m) = self.matrix {
            if self.translate.is_some() || self.rotate.is_some() || self.scale.is_some() {
                return Err(Error::invalid(
                    &key("matrix"),
                    "give either a matrix or translate, rotate and scale, not both",
                ));
            }
            finite("matrix", m.as_flattened())?;
            if m[3] != [0.0, 0.0, 0.0, 1.0] {
                return Err(Error::invalid(
                    &key("matrix"),
                    format!(
                        "the last row is {:?}, not [0, 0, 0, 1]: not an affine transform",
                        m[3]
                    ),
                ));
            }
            let linear = DMat3::from_cols_array_2d(&[
                [m[0][0], m[1][0], m[2][0]],
                [m[0][1], m[1][1], m[2][1]],
                [m[0][2], m[1][2], m[2][2]],
            ]);
            let xf = DAffine3::from_mat3_translation(linear, DVec3::new(m[0][3], m[1][3], m[2][3]));
            return invertible(&key("matrix"), xf).map(Some);
        }
        if self.translate.is_none() && self.rotate.is_none() && self.scale.is_none() {
            return Ok(None);
        }
        let t = self.translate.unwrap_or([0.0; 3]);
        let r = self.rotate.unwrap_or([0.0; 3]);
        let s = self.scale.map_or(DVec3::ONE, Scale::axes);
        finite("translate", &t)?;
        finite("rotate", &r)?;
        finite("scale", &s.to_array())?;
        if s.x == 0.0 || s.y == 0.0 || s.z == 0.0 {
            return Err(Error::invalid(&key("scale"), "a factor of 0 flattens the volume"));
        }
        let [rx, ry, rz] = r.map(f64::to_radians);
        let rotation =
            DMat3::from_rotation_z(rz) * DMat3::from_rotation_y(ry) * DMat3::from_rotation_x(rx);
        let xf = DAffine3::from_mat3_translation(
            rotation * DMat3::from_diagonal(s),
            DVec3::from_array(t),
        );
        invertible(&key("scale"), xf).map(Some)
    }
}

/// The whole placement of an instance, `instance · volume` (the instance's placement after
/// the volume's own), where `None` is the identity either way; `None` when both are.
#[must_use]
pub fn instance_placement(
    volume: Option<DAffine3>,
    instance: Option<DAffine3>,
) -> Option<DAffine3> {
    match (instance, volume) {
        (Some(i), Some(v)) => Some(i * v),
        (i, v) => i.or(v),
    }
}

/// `xf` where it has a finite inverse; else an error naming `key`.
fn invertible(key: &str, xf: DAffine3) -> Result<DAffine3> {
    let det = xf.matrix3.determinant();
    if det == 0.0 || !det.is_finite() || !xf.inverse().is_finite() {
        return Err(Error::invalid(key, format!("the transform is singular (determinant {det})")));
    }
    Ok(xf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trs_composes_as_blenders_object_matrix() {
        let p = Placement {
            translate: Some([1.0, 2.0, 3.0]),
            rotate: Some([90.0, 0.0, 90.0]),
            scale: Some(Scale::Axes([2.0, 1.0, 1.0])),
            matrix: None,
        };
        let m = p.transform("volume").unwrap().unwrap();
        // x is scaled by 2, then about x (x stays), then about z (x → y), then moved
        let x = m.transform_point3(DVec3::X);
        assert!((x - DVec3::new(1.0, 4.0, 3.0)).length() < 1e-12, "{x}");
        // y: about x → z, about z stays z
        let y = m.transform_vector3(DVec3::Y);
        assert!((y - DVec3::Z).length() < 1e-12, "{y}");
        // The same map as a matrix, rows as written
        let a = m.matrix3;
        let rows = [
            [a.x_axis.x, a.y_axis.x, a.z_axis.x, 1.0],
            [a.x_axis.y, a.y_axis.y, a.z_axis.y, 2.0],
            [a.x_axis.z, a.y_axis.z, a.z_axis.z, 3.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let by_matrix = Placement { matrix: Some(rows), ..Placement::default() };
        assert_eq!(by_matrix.transform("volume").unwrap(), Some(m));
        assert_eq!(Placement::default().transform("volume").unwrap(), None);
    }

    #[test]
    fn an_instance_is_placed_after_the_volume() {
        let volume = Placement { rotate: Some([0.0, 0.0, 90.0]), ..Placement::default() };
        let instance = Placement { translate: Some([5.0, 0.0, 0.0]), ..Placement::default() };
        let (v, i) = (volume.transform("volume").unwrap(), instance.transform("i").unwrap());
        // Turned first (x → y), then moved along the world's x
        let p = instance_placement(v, i).unwrap().transform_point3(DVec3::X);
        assert!((p - DVec3::new(5.0, 1.0, 0.0)).length() < 1e-12, "{p}");
        assert_eq!(instance_placement(v, None), v);
        assert_eq!(instance_placement(None, i), i);
        assert_eq!(instance_placement(None, None), None);
    }

    #[test]
    fn bad_placements_name_their_key() {
        let singular = [
            [1.0, 0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let cases = [
            (
                Placement { matrix: Some(singular), ..Placement::default() },
                "volumes[1].matrix",
                "singular",
            ),
            (
                Placement { matrix: Some([[0.0; 4]; 4]), ..Placement::default() },
                "volumes[1].matrix",
                "not [0, 0, 0, 1]",
            ),
            (
                Placement {
                    matrix: Some(singular),
                    translate: Some([0.0; 3]),
                    ..Placement::default()
                },
                "volumes[1].matrix",
                "not both",
            ),
            (
                Placement { scale: Some(Scale::Axes([1.0, 0.0, 1.0])), ..Placement::default() },
                "volumes[1].scale",
                "flattens",
            ),
            (
                Placement { rotate: Some([f64::NAN, 0.0, 0.0]), ..Placement::default() },
                "volumes[1].rotate",
                "not finite",
            ),
        ];
        for (p, key, needle) in cases {
            let e = p.transform("volumes[1]").unwrap_err().to_string();
            assert!(e.contains(key) && e.contains(needle), "{e}");
        }
    }
}
