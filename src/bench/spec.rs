//! What `plume bench compare` renders: methods (`--methods`) and scenes (`SCENE` plus
//! `plume render` flags).
//!
//! **Methods** are comma-separated. Each is a preset of `--method` (`point-nee`,
//! `line-nee`, `line-fnee`, `ray-march`) or `ESTIMATOR+LIGHTS` with `ESTIMATOR` one of
//! `point`, `line`, `ray-march`, `blend` (κ from `--kappa`) and `LIGHTS` one of `none`,
//! `nee`, `fnee` (e.g. `line+none`, `blend+fnee`), optionally followed by `@N` for an FNEE
//! proxy of `N` cells (`line-fnee@16`); without `@N` the scene's `--proxy-resolution`.
//!
//! **Scenes** are a [`Shot`] whose volume file is a `.vdb`, or `explosion:RES[:SEED]`, a
//! generated explosion (written once per process to a work directory so that it goes
//! through the same [`load_scene`] as any file). The shot is validated like any render's
//! (`plume bench compare` builds it from `plume render` flags or a scene file).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::load::{load_scene, LoadedScene};
use plume_core::error::{Error, Result};
use plume_engine::integrator::LightSampling;
use plume_engine::medium::Estimator;
use plume_scene::Shot;

/// One method of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodSpec {
    /// Name as given (`line-fnee@16`).
    pub name: String,
    /// Emission estimator.
    pub estimator: Estimator,
    /// Next event technique.
    pub light_sampling: LightSampling,
    /// FNEE proxy resolution, if given with `@N`.
    pub proxy_resolution: Option<u32>,
}

/// Parse a `--methods` list; `kappa` is the blend estimator's κ.
///
/// # Errors
/// [`Error::InvalidArgument`] for `--methods` naming the bad entry and the accepted forms.
pub fn parse_methods(list: &str, kappa: f64) -> Result<Vec<MethodSpec>> {
    let mut out: Vec<MethodSpec> = Vec::new();
    for raw in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let m = parse_method(raw, kappa)?;
        if out.iter().any(|o| o.name == m.name) {
            return Err(Error::invalid("--methods", format!("{raw:?} is listed twice")));
        }
        out.push(m);
    }
    if out.is_empty() {
        return Err(Error::invalid("--methods", "no method given"));
    }
    Ok(out)
}

fn parse_method(raw: &str, kappa: f64) -> Result<MethodSpec> {
    let bad = || {
        Error::invalid(
            "--methods",
            format!(
                "{raw:?}: expected a preset (point-nee, line-nee, line-fnee, ray-march) or ESTIMATOR+LIGHTS \
                 (point|line|ray-march|blend + none|nee|fnee), optionally @PROXY_RESOLUTION"
            ),
        )
    };
    let (body, proxy) = match raw.split_once('@') {
        Some((b, p)) => (b, Some(p.parse::<u32>().map_err(|_| bad())?)),
        None => (raw, None),
    };
    let estimator_of = |s: &str| match s {
        "point" => Some(Estimator::Point),
        "line" => Some(Estimator::Line),
        "ray-march" => Some(Estimator::RayMarch),
        "blend" => Some(Estimator::Blend { kappa }),
        _ => None,
    };
    let (estimator, light_sampling) = match body {
        "point-nee" => (Estimator::Point, LightSampling::Nee),
        "line-nee" => (Estimator::Line, LightSampling::Nee),
        "line-fnee" => (Estimator::Line, LightSampling::Fnee),
        "ray-march" => (Estimator::RayMarch, LightSampling::None),
        _ => {
            let (e, l) = body.split_once('+').ok_or_else(bad)?;
            let ls = match l {
                "none" => LightSampling::None,
                "nee" => LightSampling::Nee,
                "fnee" => LightSampling::Fnee,
                _ => return Err(bad()),
            };
            (estimator_of(e).ok_or_else(bad)?, ls)
        }
    };
    if proxy.is_some() && light_sampling != LightSampling::Fnee {
        return Err(Error::invalid(
            "--methods",
            format!("{raw:?}: @PROXY applies to FNEE methods only"),
        ));
    }
    Ok(MethodSpec { name: raw.to_string(), estimator, light_sampling, proxy_resolution: proxy })
}

/// A scene ready to render, with the shot that built it.
pub struct BenchScene {
    /// The shot (its output is a placeholder, never written).
    pub shot: Shot,
    /// The loaded scene.
    pub loaded: LoadedScene,
    /// The scene as given (`explosion:256` or the file path).
    pub spec: String,
    /// How the scene was given besides its spec, for reports: render flags or a scene
    /// file.
    pub flags: Vec<String>,
    /// Seconds spent generating (explosions) and loading.
    pub load_seconds: f64,
}

/// Generated files of this process (regenerated once per process, then reused).
static GENERATED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The `.vdb` behind a scene spec: the file itself, or a generated explosion written to
/// `work_dir` (once per process).
///
/// # Errors
/// A malformed `explosion:` spec, or the explosion cannot be written.
pub fn scene_file(spec: &str, work_dir: &Path) -> Result<PathBuf> {
    // A spec read from a scene file has that file's directory in front
    let name =
        Path::new(spec).file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let Some(rest) = name.strip_prefix("explosion:") else { return Ok(PathBuf::from(spec)) };
    let bad = || {
        Error::invalid(
            "SCENE",
            format!("{spec:?}: expected explosion:RESOLUTION[:SEED], e.g. explosion:256"),
        )
    };
    let mut parts = rest.split(':');
    let resolution: u32 = parts.next().ok_or_else(bad)?.parse().map_err(|_| bad())?;
    let seed: u64 = match parts.next() {
        Some(s) => s.parse().map_err(|_| bad())?,
        None => 1,
    };
    if parts.next().is_some() || !(8..=4096).contains(&resolution) {
        return Err(bad());
    }
    let path = work_dir.join(format!("explosion-{resolution}-seed{seed}.vdb"));
    let mut done =
        GENERATED.lock().map_err(|_| Error::Scene("bench: generator lock poisoned".into()))?;
    if !done.contains(&path) {
        std::fs::create_dir_all(work_dir)
            .map_err(|source| Error::Write { path: work_dir.to_path_buf(), source })?;
        let params = plume_synth::ExplosionParams { resolution, seed, ..Default::default() };
        let ex = plume_synth::explosion(&params);
        // With its velocity, as `plume synth explosion` writes it (`--velocity-grid velocity`)
        let [vx, vy, vz] = plume_synth::velocity::explosion_velocity(&params, &ex.density);
        let velocity = crate::vdb::VectorGrid { name: "velocity", components: [&vx, &vy, &vz] };
        crate::vdb::write_grids(&path, &[&ex.density, &ex.temperature], &[velocity])?;
        done.push(path.clone());
    }
    Ok(path)
}

/// Load `shot`, whose volume file is a scene spec (a file or `explosion:RES[:SEED]`,
/// generated into `work_dir`).
///
/// # Errors
/// See [`scene_file`], [`Shot::validate`] and [`load_scene`].
pub fn load(mut shot: Shot, flags: Vec<String>, work_dir: &Path) -> Result<BenchScene> {
    let t = std::time::Instant::now();
    let spec = shot.scene.volume.file.display().to_string();
    shot.scene.volume.file = scene_file(&spec, work_dir)?;
    load_from(shot, spec, flags, t)
}

/// Load `shot`, whose volume file is a file (never a generated explosion).
///
/// # Errors
/// See [`Shot::validate`] and [`load_scene`].
pub fn load_file(shot: Shot, flags: Vec<String>) -> Result<BenchScene> {
    let spec = shot.scene.volume.file.display().to_string();
    load_from(shot, spec, flags, std::time::Instant::now())
}

/// Validate and load `shot` (its volume file a file now), started at `t`.
fn load_from(
    shot: Shot,
    spec: String,
    flags: Vec<String>,
    t: std::time::Instant,
) -> Result<BenchScene> {
    let shot = shot.validate()?.into_inner();
    let loaded = load_scene(&shot.scene, &shot.scene.volume.file, &shot.settings, None)?;
    Ok(BenchScene { shot, loaded, spec, flags, load_seconds: t.elapsed().as_secs_f64() })
}

/// The output of a benchmark's shot: a placeholder, never written.
pub const UNUSED_OUTPUT: &str = "plume-bench-unused.exr";

/// A shot of `spec` for a benchmark: its output is a placeholder that is never written
/// ([`UNUSED_OUTPUT`]).
#[must_use]
pub fn bench_shot(spec: &str) -> Shot {
    Shot::new(spec, UNUSED_OUTPUT)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_parse_presets_combinations_and_proxies() {
        let m = parse_methods("point-nee, line+none,blend+fnee,line-fnee@16", 4.0).unwrap();
        assert_eq!(m.len(), 4);
        assert_eq!((m[0].estimator, m[0].light_sampling), (Estimator::Point, LightSampling::Nee));
        assert_eq!((m[1].estimator, m[1].light_sampling), (Estimator::Line, LightSampling::None));
        assert_eq!(m[2].estimator, Estimator::Blend { kappa: 4.0 });
        assert_eq!(m[3].proxy_resolution, Some(16));
        for bad in
            ["", "line", "line+sun", "fast", "point-nee@16", "line-fnee@x", "line-fnee,line-fnee"]
        {
            assert!(parse_methods(bad, 4.0).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn explosion_specs_are_found_behind_a_directory() {
        let dir = std::env::temp_dir().join(format!("plume-spec-test-{}", std::process::id()));
        let p = scene_file("docs/bench/explosion:16:3", &dir).unwrap();
        assert_eq!(p, dir.join("explosion-16-seed3.vdb"));
        assert!(p.exists());
        assert_eq!(scene_file("a/b.vdb", &dir).unwrap(), PathBuf::from("a/b.vdb"));
        assert!(scene_file("explosion:x", &dir).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
