//! Operations between strokes: `sculpt` operations (CSG, emboss, resampling…), a CSG primitive
//! at the cursor from the panel, and saving a scene file that reloads the model.

use std::path::PathBuf;

use anyhow::Context as _;
use glam::DVec3;
use sim_core::csg::CsgOp;
use sim_core::scene::ResampleOptions;

use super::{SimCore, spacings};
use crate::live::scene_file::SceneObjectSpec;
use crate::sculpt::script::{Generate, Op};

/// The most points a CSG primitive from the panel is sampled with.
pub const MAX_PRIMITIVE_POINTS: usize = 40_000;

impl SimCore {
    /// Run a `sculpt` operation (CSG, emboss, paint, resampling…) between strokes. A CSG result
    /// replaces its inputs on screen; if it consumed the sculpted object the region moves to it.
    pub fn run_op(&mut self, op: &Op) -> anyhow::Result<(&'static str, String)> {
        if self.stroke.is_some() {
            self.release()?;
        }
        self.scene.close_region()?;
        let before = self.names.len();
        let dt = self.file.region.dt;
        let result = crate::sculpt::ops::run_op(
            &mut self.scene,
            &mut self.names,
            op,
            dt,
            &self.dir,
            &self.fit,
        );
        self.hidden.resize(self.names.len(), false);
        self.spacing = spacings(&self.scene);
        if let Op::Csg { a, b, .. } = op
            && self.names.len() > before
        {
            let result = self.names.len() - 1;
            for n in [a, b] {
                if let Some(i) = self.names.iter().position(|x| x == n) {
                    self.hidden[i] = true;
                    if i == self.region_object {
                        self.region_object = result;
                    }
                }
            }
        }
        // Reopened whether or not the operation worked: a failed one leaves the scene as it was.
        self.params.resample = self
            .params
            .resample
            .map(|_| ResampleOptions::new(self.spacing[self.region_object]));
        self.scene.open_region(
            self.region_object,
            self.bounds.0,
            self.bounds.1,
            self.params,
        )?;
        // CSG and embossing refit the whole object from new points: resample its region.
        if let (Ok(_), Some(opts), Op::Csg { .. } | Op::Emboss { .. }) =
            (&result, self.params.resample, op)
        {
            let r = self.scene.resample_region(&opts)?;
            tracing::debug!(?r, "region resampled after the operation");
        }
        self.points_replaced();
        result
    }

    /// Add a primitive at `at` and combine it with the sculpted object: `Difference` carves it
    /// out, `Union` adds it, `Intersection` keeps the overlap. The primitive is sampled at about
    /// the sculpted object's spacing.
    pub fn csg_primitive(
        &mut self,
        op: CsgOp,
        shape: &str,
        size: f64,
        at: DVec3,
    ) -> anyhow::Result<(&'static str, String)> {
        anyhow::ensure!(at.is_finite(), "the cursor is not in the scene yet");
        anyhow::ensure!(
            size.is_finite() && size > 0.0,
            "primitive size must be positive (got {size})"
        );
        let h = self.spacing[self.region_object];
        let area = match shape {
            "sphere" => 4.0 * std::f64::consts::PI * size * size,
            "box" => 24.0 * size * size,
            other => anyhow::bail!("unknown primitive `{other}` (sphere, box)"),
        };
        let points = ((area / (h * h)) as usize).clamp(200, MAX_PRIMITIVE_POINTS);
        let n = self.names.len();
        let name = format!("{shape}_{n}");
        let spec = SceneObjectSpec {
            name: name.clone(),
            file: None,
            generate: Some(Generate {
                shape: shape.into(),
                size,
                size2: if shape == "box" { 0.1 * size } else { 0.0 },
                points,
                seed: n as u64,
            }),
            size: None,
            offset: at.to_array(),
            dynamic: Some(false),
            material: None,
        };
        let object = crate::sculpt::load_object(&spec.object_spec(), &self.dir, &self.fit)?;
        self.scene.add(object);
        self.names.push(name.clone());
        self.hidden.push(true); // an operand: consumed by the operation below
        self.spacing = spacings(&self.scene);
        let a = self.names[self.region_object].clone();
        self.run_op(&Op::Csg {
            op,
            a,
            b: name,
            result: format!("csg_{n}"),
        })
    }

    /// Write the visible objects as `<name>.ply` and a `scene.toml` that loads them with this
    /// session's region, materials and settings into `dir`; returns the scene file's path.
    pub fn save_scene(&self, dir: &std::path::Path) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let mut file = self.file.clone();
        file.object.clear();
        for ((o, name), _) in self
            .scene
            .objects()
            .iter()
            .zip(&self.names)
            .zip(&self.hidden)
            .filter(|(_, h)| !**h)
        {
            let path = dir.join(format!("{name}.ply"));
            let points = sim_core::PointSet {
                positions: o.positions.clone(),
                normals: Some(o.normals.clone()),
                colors: Some(o.colors.clone()),
            };
            let f = std::fs::File::create(&path)
                .with_context(|| format!("creating {}", path.display()))?;
            sim_core::io::write_points_ply(std::io::BufWriter::new(f), &points, false)?;
            let spec = self.file.object.iter().find(|s| s.name == *name);
            file.object.push(SceneObjectSpec {
                name: name.clone(),
                file: Some(format!("{name}.ply")),
                generate: None,
                size: None,
                offset: [0.0; 3],
                dynamic: Some(*name == self.names[self.region_object]),
                material: spec.and_then(|s| s.material.clone()),
            });
        }
        file.region.object = self.names[self.region_object].clone();
        file.tools.selected = self.selected;
        let path = dir.join("scene.toml");
        std::fs::write(&path, file.to_toml()?)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    }
}
