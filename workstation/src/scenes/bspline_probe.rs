//! The B-spline sculpting scene (seed 004 §4.2): a bicubic patch with its mass-spring dual,
//! touched and sculpted by an ellipsoid probe; press the button to push (from the front) or pull
//! (from behind).
//!
//! Per haptic tick the scene runs [`ProbeSculptor::tick`] at the probe pose (1 kHz), converts
//! the force and local model to the wire once ([`sim_core::haptic::HapticOutput::to_command`]) and, at the display
//! rate, recovers the control net (`P = A⁻¹ M A⁻ᵀ`). [`BsplineProbeScene::run_script`] drives it
//! headless along a scripted path and reports what a user would have felt and made; it also
//! renders every command with the server's [`ModelRenderer`] at the same cursor, so the report
//! shows the workstation and the server agree.

use glam::{DQuat, DVec3};
use protocol::ModelRenderer;
use sim_core::bspline_surface::{BicubicPatch, MeshParams, ProbeSculptor, SurfaceError};
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbeError, ProbePose,
};

/// Why the scene could not be built or run.
#[derive(Debug)]
pub enum SceneError {
    /// The surface, mesh or dual map was rejected.
    Surface(SurfaceError),
    /// The probe or its contact parameters were rejected.
    Probe(ProbeError),
    /// The script is empty, unsorted or non-finite.
    BadScript,
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Surface(e) => write!(f, "surface: {e}"),
            Self::Probe(e) => write!(f, "probe: {e}"),
            Self::BadScript => f.write_str("script must have finite keyframes in increasing time"),
        }
    }
}

impl std::error::Error for SceneError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Surface(e) => Some(e),
            Self::Probe(e) => Some(e),
            Self::BadScript => None,
        }
    }
}

impl From<SurfaceError> for SceneError {
    fn from(e: SurfaceError) -> Self {
        Self::Surface(e)
    }
}

impl From<ProbeError> for SceneError {
    fn from(e: ProbeError) -> Self {
        Self::Probe(e)
    }
}

/// Scene settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneConfig {
    /// Control points (and mass points) per side.
    pub n: usize,
    /// Half the side of the square patch, m.
    pub half_size: f64,
    /// Mesh material.
    pub mesh: MeshParams,
    /// Probe semi-axes, m.
    pub probe_axes: DVec3,
    /// Contact springs (feel and tool strength).
    pub contact: ContactParams,
    /// Haptic tick, s.
    pub dt: f64,
    /// Control-net updates per second (the display rate).
    pub display_hz: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            n: 30,
            half_size: 0.05,
            mesh: MeshParams {
                plastic_rate: 5.0,
                ..MeshParams::REFERENCE
            },
            probe_axes: DVec3::new(0.012, 0.008, 0.008),
            contact: ContactParams {
                surface_stiffness: 5.0e6,
                surface_damping: 1.5e4,
                method: DirectionMethod::SurfaceNormal,
                magnitude: MagnitudeMethod::SpringSum,
            },
            dt: 0.001,
            display_hz: 50.0,
        }
    }
}

/// One point of a scripted probe path; poses are interpolated linearly (slerp) between them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Time, s.
    pub t: f64,
    /// Probe centre, m.
    pub position: DVec3,
    /// Probe orientation.
    pub orientation: DQuat,
    /// Stylus button held (sculpt) from this keyframe to the next.
    pub pressed: bool,
}

/// What a headless run felt and made.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SceneReport {
    /// Haptic ticks run.
    pub ticks: usize,
    /// Control-net updates.
    pub display_updates: usize,
    /// Largest force on the user, N.
    pub peak_force_n: f64,
    /// Largest force while pressing (the material's reaction), N.
    pub peak_reaction_n: f64,
    /// Largest |server-rendered − workstation| force at the same cursor, N (wire is f32).
    pub max_model_mismatch_n: f64,
    /// Deepest point of the patch below its start plane at the end, m.
    pub final_dent_m: f64,
    /// Highest point above the start plane at the end, m.
    pub final_bulge_m: f64,
    /// Largest distance of the displayed patch from the mass points at their parameters, m.
    pub display_error_m: f64,
}

/// The scene: sculptor, probe and display clock.
#[derive(Debug)]
pub struct BsplineProbeScene {
    config: SceneConfig,
    sculptor: ProbeSculptor,
    probe: Probe,
    since_display: f64,
}

impl BsplineProbeScene {
    /// A flat patch in `z = 0` and a probe at the origin.
    pub fn new(config: SceneConfig) -> Result<Self, SceneError> {
        let patch = BicubicPatch::flat(config.n, config.half_size)?;
        let sculptor =
            ProbeSculptor::new(patch, config.mesh, config.contact, 0.005, 4.0 * config.dt)?;
        Ok(Self {
            config,
            sculptor,
            probe: Probe::ellipsoid(config.probe_axes)?,
            since_display: 0.0,
        })
    }

    /// The sculptor (mesh, patch, dual).
    pub fn sculptor(&self) -> &ProbeSculptor {
        &self.sculptor
    }

    /// Change the probe's size and shape at run time.
    pub fn set_probe_axes(&mut self, axes: DVec3) -> Result<(), SceneError> {
        Ok(self.probe.set_semi_axes(axes)?)
    }

    /// The default demonstration: touch, press in from above, release, pass through, pull a
    /// bulge from behind with the probe turned on end, release, retreat (4 s).
    pub fn demo_script() -> Vec<Keyframe> {
        let flat = DQuat::IDENTITY;
        let upright = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let k = |t: f64, z: f64, x: f64, o: DQuat, pressed: bool| Keyframe {
            t,
            position: DVec3::new(x, 0.0, z),
            orientation: o,
            pressed,
        };
        vec![
            k(0.0, 0.02, 0.0, flat, false),
            k(0.4, 0.006, 0.0, flat, false),
            k(0.6, 0.006, 0.0, flat, true),
            k(1.2, 0.002, 0.015, flat, true),
            k(1.5, 0.002, 0.015, flat, false),
            k(2.0, -0.02, -0.015, upright, false),
            k(2.3, -0.014, -0.015, upright, true),
            k(3.0, -0.006, -0.015, upright, true),
            k(3.3, -0.006, -0.015, upright, false),
            k(4.0, -0.03, -0.015, upright, false),
        ]
    }

    fn pose_at(script: &[Keyframe], t: f64) -> (ProbePose, bool) {
        let i = script
            .partition_point(|k| k.t <= t)
            .clamp(1, script.len() - 1);
        let (a, b) = (&script[i - 1], &script[i]);
        let s = if b.t > a.t {
            ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let pose = ProbePose {
            position: a.position.lerp(b.position, s),
            orientation: a.orientation.slerp(b.orientation, s).normalize(),
        };
        (pose, a.pressed && t < b.t)
    }

    /// Run `script` from its first to its last keyframe at the haptic rate.
    pub fn run_script(&mut self, script: &[Keyframe]) -> Result<SceneReport, SceneError> {
        let ok = !script.is_empty()
            && script.windows(2).all(|w| w[1].t > w[0].t)
            && script
                .iter()
                .all(|k| k.t.is_finite() && k.position.is_finite());
        if !ok {
            return Err(SceneError::BadScript);
        }
        let dt = self.config.dt;
        let (t0, t1) = (script[0].t, script[script.len() - 1].t);
        let ticks = ((t1 - t0) / dt).round() as usize;
        let mut report = SceneReport::default();
        let mut server = ModelRenderer::new();
        let mut last = script[0].position;
        for tick in 0..ticks {
            let (pose, pressed) = Self::pose_at(script, t0 + tick as f64 * dt);
            self.probe.set_pose(pose)?;
            let v = (pose.position - last) / dt;
            last = pose.position;
            let out = self.sculptor.tick(&self.probe, v, pressed, dt)?;
            let f = out.output.force;
            report.peak_force_n = report.peak_force_n.max(f.length());
            if pressed {
                report.peak_reaction_n = report.peak_reaction_n.max(f.length());
            }
            let command = out.output.to_command(tick as u32, 0);
            server.reset();
            let at = pose.position.as_vec3();
            let rendered = server.render(&command, at, v.as_vec3(), 0).as_dvec3();
            let mismatch = (rendered - f).length();
            report.max_model_mismatch_n = report.max_model_mismatch_n.max(mismatch);
            self.since_display += dt;
            if self.since_display >= 1.0 / self.config.display_hz {
                self.since_display = 0.0;
                self.sculptor.update_display();
                report.display_updates += 1;
            }
            report.ticks += 1;
        }
        let n = self.config.n;
        let patch = self.sculptor.update_display().clone();
        let mesh = self.sculptor.mesh().positions();
        for (q, p) in mesh.iter().enumerate() {
            report.final_dent_m = report.final_dent_m.max(-p.z);
            report.final_bulge_m = report.final_bulge_m.max(p.z);
            let (u, w) = (q / n, q % n);
            let s = patch.point(
                sim_core::bspline_surface::mass_parameter(n, u),
                sim_core::bspline_surface::mass_parameter(n, w),
            );
            report.display_error_m = report.display_error_m.max((s - *p).length());
        }
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_sculpts_a_dent_and_a_bulge_and_the_server_agrees() {
        let mut scene = BsplineProbeScene::new(SceneConfig::default()).unwrap();
        let r = scene.run_script(&BsplineProbeScene::demo_script()).unwrap();
        assert_eq!(r.ticks, 4000);
        assert_eq!(r.display_updates, 200, "50 Hz display over 4 s");
        // Plastic material: both strokes leave a mark (mm scale).
        assert!(r.final_dent_m > 0.001 && r.final_bulge_m > 0.001, "{r:?}");
        assert!(r.peak_reaction_n > 0.0 && r.peak_force_n.is_finite());
        // The server renders each command at its own cursor to the f32 wire's precision.
        assert!(
            r.max_model_mismatch_n <= 1e-5 * r.peak_force_n.max(1.0),
            "{r:?}"
        );
        assert!(r.display_error_m < 1e-12, "{r:?}");
    }

    #[test]
    fn bad_scripts_are_rejected() {
        let mut scene = BsplineProbeScene::new(SceneConfig::default()).unwrap();
        assert!(matches!(scene.run_script(&[]), Err(SceneError::BadScript)));
        let mut s = BsplineProbeScene::demo_script();
        s[3].t = s[1].t;
        assert!(matches!(scene.run_script(&s), Err(SceneError::BadScript)));
    }
}
