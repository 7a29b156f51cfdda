//! Point edits on scene objects: appending up-sampled points, replacing an object's points
//! (down-sampling, CSG, embossing) and refitting its field, keeping an open region consistent.

use super::{Region, Scene, SceneError};
use crate::PointSet;
use crate::local_fit::FitParams;
use crate::resample::Insertion;
use crate::scene::SceneObject;

impl Scene {
    /// Append points to `object` (e.g. up-sampling insertions, colour from the parent point).
    /// They follow the field at once but carry no local field until [`Scene::refit`].
    pub fn insert_points(&mut self, object: usize, items: &[Insertion]) -> Result<(), SceneError> {
        let obj = self
            .objects
            .get_mut(object)
            .ok_or(SceneError::NoObject(object))?;
        let region = self.region.as_mut().filter(|r| r.object == object);
        append_points(obj, region, items);
        Ok(())
    }

    /// Replace `object`'s points (after down-sampling, CSG, embossing…) and refit its field.
    /// An open region on it is closed first (ending the stroke) and reopened on the new field.
    pub fn replace_points(
        &mut self,
        object: usize,
        points: PointSet,
        fit: &FitParams,
    ) -> Result<(), SceneError> {
        if object >= self.objects.len() {
            return Err(SceneError::NoObject(object));
        }
        let reopen = match &self.region {
            Some(r) if r.object == object => Some((r.bounds, r.params)),
            _ => None,
        };
        if reopen.is_some() {
            self.close_region()?;
        }
        let obj = &mut self.objects[object];
        let name = std::mem::take(&mut obj.name);
        *obj = SceneObject::fit(name, points, fit)?;
        if let Some(((min, max), params)) = reopen {
            self.open_region(object, min, max, params)?;
        }
        Ok(())
    }

    /// Refit `object`'s field from its current points and normals (see [`Scene::replace_points`]).
    pub fn refit(&mut self, object: usize, fit: &FitParams) -> Result<(), SceneError> {
        let obj = self
            .objects
            .get(object)
            .ok_or(SceneError::NoObject(object))?;
        let points = PointSet {
            positions: obj.positions.clone(),
            normals: Some(obj.normals.clone()),
            colors: Some(obj.colors.clone()),
        };
        self.replace_points(object, points, fit)
    }

    /// Mutable access to an object's points and colours for tools that edit them in place
    /// (painting). Positions must stay on the surface; see [`Scene::refit`] otherwise.
    pub fn object_mut(&mut self, object: usize) -> Option<&mut SceneObject> {
        self.objects.get_mut(object)
    }
}

/// Append `items` to `obj` (colour from the parent point) and, if its region is open, make the
/// new points candidates of the follower.
pub(super) fn append_points(
    obj: &mut SceneObject,
    region: Option<&mut Region>,
    items: &[Insertion],
) {
    let first = obj.positions.len();
    for it in items {
        let color = obj
            .colors
            .get(it.parent)
            .copied()
            .unwrap_or([128, 128, 128]);
        obj.positions.push(it.position);
        obj.normals.push(it.normal);
        obj.colors.push(color);
    }
    if let Some(region) = region {
        let spec = *region.model.spec();
        region.follower.grow(obj.positions.len());
        for i in first as u32..obj.positions.len() as u32 {
            region.follower.mark_changed(i);
        }
        region.inside.extend(
            (first as u32..obj.positions.len() as u32)
                .filter(|&i| spec.contains(obj.positions[i as usize])),
        );
    }
}
