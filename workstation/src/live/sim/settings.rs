//! What can change while a session runs (the window's panel): tools, material, integrator and
//! step, checked as a scene file's are.

use anyhow::Context as _;
use glam::DVec3;
use sim_core::dynamics::NodeParams;
use sim_core::probe::Probe;

use super::SimCore;
use crate::live::scene_file::{SceneFile, ToolDefaults};

/// What can change while a session runs (the window's panel): tools, material, integrator and
/// step.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Contact, rope, paint and probe settings (`selected` is not used: see
    /// [`super::SimCommand::Select`]).
    pub tools: ToolDefaults,
    /// The sculpted material's node parameters.
    pub material: NodeParams,
    /// `symplectic_euler`, `forward_euler` or `backward_euler`.
    pub integrator: String,
    /// Simulation step (s).
    pub dt: f64,
}

impl Settings {
    /// A scene file's settings.
    pub fn of(file: &SceneFile) -> Self {
        let region = file.script().region;
        Self {
            tools: file.tools.clone(),
            material: region.as_ref().and_then(|r| r.node).unwrap_or_default(),
            integrator: file.region.integrator.clone(),
            dt: file.region.dt,
        }
    }

    fn region_part(&self) -> (NodeParams, &str, f64) {
        (self.material, &self.integrator, self.dt)
    }
}

impl SimCore {
    /// The settings in force.
    pub fn settings(&self) -> Settings {
        Settings::of(&self.file)
    }

    /// Change tools, material, integrator or step at run time. The values are checked as a
    /// scene file's are (errors name the field, e.g. `tools.rope.stiffness`); on error nothing
    /// changes. Tool settings apply from the next press (the force thread's from the next
    /// published tool); a new material, integrator or step lets go of an engaged stroke and
    /// reopens the region over the current shape.
    pub fn configure(&mut self, s: &Settings) -> anyhow::Result<()> {
        let mut file = self.file.clone();
        file.tools = ToolDefaults {
            selected: file.tools.selected,
            ..s.tools.clone()
        };
        file.region.node = Some(s.material);
        file.region.integrator.clone_from(&s.integrator);
        file.region.dt = s.dt;
        file.validate()?;
        let probe = Probe::ellipsoid(DVec3::from(file.tools.probe.semi_axes))?;
        let region = file.script().region.context("the scene has no region")?;
        let params = sim_core::scene::RegionParams {
            resample: self.params.resample,
            follow: self.params.follow,
            ..crate::sculpt::region_params(&region)
        };
        if Settings::of(&self.file).region_part() != s.region_part() {
            if self.stroke.is_some() {
                self.release()?;
            }
            self.scene.close_region()?;
            self.scene
                .open_region(self.region_object, self.bounds.0, self.bounds.1, params)?;
            self.params = params;
            self.points_replaced();
        }
        self.file = file;
        self.probe = probe;
        Ok(())
    }
}
