//! What the simulation hands a shared scene and takes from it (`crate::share`): the sculpted
//! object's whole point set after each local commit, and a newer state to adopt.

use glam::DVec3;
use sim_core::PointSet;
use sim_core::scene::{ResampleOptions, SceneObject};

use super::SimCore;

/// The sculpted object's points, as shared.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedPoints {
    /// The shared scene's version these points were made from: the one adopted last (0: none),
    /// or, to adopt, the version they are.
    pub version: u64,
    /// The sculpted object's name.
    pub object: String,
    /// The objects shown (the others were consumed by operations, e.g. a CSG's operands).
    pub visible: Vec<String>,
    /// Positions (m).
    pub positions: Vec<DVec3>,
    /// Unit normals.
    pub normals: Vec<DVec3>,
    /// sRGB colours.
    pub colors: Vec<[u8; 3]>,
}

impl SimCore {
    /// The sculpted object's points (a copy: O(points), once per commit).
    pub fn shared_points(&self) -> SharedPoints {
        let o = &self.scene.objects()[self.region_object];
        SharedPoints {
            version: 0,
            object: self.names[self.region_object].clone(),
            visible: self
                .names
                .iter()
                .zip(&self.hidden)
                .filter(|(_, h)| !**h)
                .map(|(n, _)| n.clone())
                .collect(),
            positions: o.positions.clone(),
            normals: o.normals.clone(),
            colors: o.colors.clone(),
        }
    }

    /// Take another station's state: the sculpted object's points become `s`'s (its field is
    /// refitted and the region reopened on it, as after an operation). An object this station
    /// does not have (made by an operation elsewhere, e.g. a CSG result) is added and becomes
    /// the sculpted one; the objects shown are the author's. The caller waits for a stroke in
    /// progress to end first ([`SimCore::engaged`]).
    pub fn adopt(&mut self, s: &SharedPoints) -> anyhow::Result<()> {
        anyhow::ensure!(
            s.positions.len() == s.normals.len() && s.positions.len() == s.colors.len(),
            "a shared state with {} positions, {} normals and {} colours",
            s.positions.len(),
            s.normals.len(),
            s.colors.len()
        );
        let points = PointSet {
            positions: s.positions.clone(),
            normals: Some(s.normals.clone()),
            colors: Some(s.colors.clone()),
        };
        match self.names.iter().position(|n| *n == s.object) {
            Some(i) if i == self.region_object => {
                self.scene.replace_points(i, points, &self.fit)?;
            }
            found => {
                // The region moves to another object (as after a CSG that consumed it).
                self.scene.close_region()?;
                let i = match found {
                    Some(i) => {
                        self.scene.replace_points(i, points, &self.fit)?;
                        i
                    }
                    None => {
                        let object = SceneObject::fit(s.object.clone(), points, &self.fit)?;
                        self.names.push(s.object.clone());
                        self.hidden.push(false);
                        self.scene.add(object)
                    }
                };
                self.region_object = i;
                self.spacing = super::spacings(&self.scene);
                self.params.resample = self
                    .params
                    .resample
                    .map(|_| ResampleOptions::new(self.spacing[i]));
                self.scene
                    .open_region(i, self.bounds.0, self.bounds.1, self.params)?;
            }
        }
        for (name, hidden) in self.names.iter().zip(self.hidden.iter_mut()) {
            *hidden = !s.visible.contains(name);
        }
        self.spacing = super::spacings(&self.scene);
        self.points_replaced();
        Ok(())
    }
}
