//! The integrator a scene description asks for: its estimators, light sampling, tracking
//! and splitting resolved from the description's `[integrator]` and `[medium]`.

use plume_scene::{Estimator, LightSampling, SceneDescription};

use super::volpath::Integrator;

impl Integrator {
    /// The integrator this description asks for.
    #[must_use]
    pub fn for_scene(scene: &SceneDescription) -> Integrator {
        let (estimator, light_sampling) = scene.integrator.parts();
        Integrator::for_scene_with(scene, estimator, light_sampling)
    }

    /// The integrator this description asks for, with another estimator and light
    /// sampling (benchmarks compare them on one scene); the tracking is resolved for them.
    #[must_use]
    pub fn for_scene_with(
        scene: &SceneDescription,
        estimator: Estimator,
        light_sampling: LightSampling,
    ) -> Integrator {
        // Where paths scatter the camera segment is ray-marched unless asked otherwise: its
        // emission is then exact along each ray, and its collision can be forced
        let camera_estimator =
            scene.integrator.camera_estimator.map(|k| k.with_kappa(scene.integrator.kappa));
        Integrator {
            estimator,
            camera_estimator: camera_estimator.or(scene.scatters().then_some(Estimator::RayMarch)),
            light_sampling,
            mis: scene.integrator.mis,
            max_depth: if scene.scatters() { scene.integrator.max_depth } else { 0 },
            tracking: scene.integrator.tracking.resolve(estimator, light_sampling),
            split: scene.integrator.split,
            split_by: scene.integrator.split_by,
            camera_collision: scene.integrator.camera_collision.collision(),
            point_lookup: scene.integrator.point_lookup,
        }
    }
}
