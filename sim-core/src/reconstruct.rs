//! The whole construction pipeline: k-NN → normals → local fits → global field, with a stage
//! observer so the caller can time stages (sim-core reads no clock).
//!
//! Contract: deterministic for a given input and parameters (the parallel stages write disjoint
//! outputs), never panics on a validated [`PointSet`], returns finite normals.

use glam::DVec3;

use crate::field::{FieldError, GlobalField, Progress};
use crate::knn::{KnnGraph, PointIndex};
use crate::local_fit::FitParams;
use crate::normals;
use crate::pointset::{PointSet, PointSetError};

/// What to do with the normals a point set brings.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NormalPolicy {
    /// Keep given normals as they are; estimate (PCA + MST orientation) only missing ones.
    #[default]
    Keep,
    /// [`NormalPolicy::Keep`], except that given normals whose signs look like noise
    /// ([`normals::unoriented_share_in`] above [`normals::UNORIENTED_SHARE`]: some scanners
    /// write unoriented normals, and a field fitted to them breaks up) are first made consistent
    /// over the MST, each part's top facing `+z` ([`Reconstruction::reoriented`] says so). The
    /// check reads the k-NN graph the fit builds anyway.
    KeepConsistent,
    /// Keep the given normals' lines but make their signs consistent over the MST, keeping the
    /// global sign most given normals agree with (repairs a minority of flipped normals).
    Reorient,
    /// Ignore given normals: PCA + MST orientation for all.
    Estimate,
}

/// A construction stage, reported to a [`StageObserver`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// k-d tree build and k-NN queries.
    Knn,
    /// Normal estimation and orientation.
    Normals,
    /// Local fits, outlier rejection and the support index.
    Fit,
}

/// Receives stage boundaries (e.g. to time them).
pub trait StageObserver {
    /// `stage` starts.
    fn begin(&mut self, stage: Stage);
    /// `stage` ended.
    fn end(&mut self, stage: Stage);
}

/// An observer that ignores stages.
#[derive(Debug, Clone, Copy, Default)]
pub struct IgnoreStages;

impl StageObserver for IgnoreStages {
    fn begin(&mut self, _: Stage) {}
    fn end(&mut self, _: Stage) {}
}

/// Why reconstruction failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReconstructError {
    /// The point set is unusable.
    #[error(transparent)]
    Points(#[from] PointSetError),
    /// The field could not be built.
    #[error(transparent)]
    Field(#[from] FieldError),
}

/// The result of [`reconstruct`].
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// The implicit surface.
    pub field: GlobalField,
    /// The oriented unit normals used for the fits.
    pub normals: Vec<DVec3>,
    /// How many normals were estimated by PCA.
    pub estimated_normals: usize,
    /// With [`NormalPolicy::KeepConsistent`], the share of side-by-side neighbours whose given
    /// normals faced apart when that made them consistent; `None` when it left them alone.
    pub reoriented: Option<f64>,
}

/// Fit `points` into a [`GlobalField`].
pub fn reconstruct(
    points: &PointSet,
    params: &FitParams,
    policy: NormalPolicy,
    observer: &mut dyn StageObserver,
    progress: &dyn Progress,
) -> Result<Reconstruction, ReconstructError> {
    let mut points = points.clone();
    points.validate()?;
    let pos = &points.positions;
    if params.k < 2 {
        return Err(FieldError::Param("k must be at least 2 (a point and a neighbour)").into());
    }
    observer.begin(Stage::Knn);
    let index = PointIndex::new(pos);
    let knn = KnnGraph::build(pos, &index, params.k);
    observer.end(Stage::Knn);

    observer.begin(Stage::Normals);
    let given = points
        .normals
        .take()
        .filter(|_| policy != NormalPolicy::Estimate);
    let mut reoriented = None;
    let (normals, estimated) = match given {
        None => {
            let mut n = normals::estimate_pca(pos, &knn);
            normals::orient_consistently(pos, &knn, &mut n);
            let count = n.len();
            (n, count)
        }
        Some(mut given) => {
            if policy == NormalPolicy::KeepConsistent {
                reoriented = normals::orient_if_unoriented_in(pos, &knn, &mut given);
            }
            let missing: Vec<bool> = given.iter().map(|n| *n == DVec3::ZERO).collect();
            let count = missing.iter().filter(|m| **m).count();
            let mut n = given.clone();
            normals::fill_missing(pos, &knn, &mut n);
            if policy == NormalPolicy::Reorient || count > 0 {
                // Orient everything consistently, then restore the given signs' majority; with
                // `Keep`, only the estimated normals take the propagated sign.
                let mut oriented = n.clone();
                normals::orient_consistently(pos, &knn, &mut oriented);
                normals::match_majority(&given, &mut oriented);
                for i in 0..n.len() {
                    if policy == NormalPolicy::Reorient || missing[i] {
                        n[i] = oriented[i];
                    }
                }
            }
            (n, count)
        }
    };
    observer.end(Stage::Normals);

    observer.begin(Stage::Fit);
    let field = GlobalField::build_indexed(pos, &normals, &knn, &index, params, progress)?;
    observer.end(Stage::Fit);
    Ok(Reconstruction {
        field,
        normals,
        estimated_normals: estimated,
        reoriented,
    })
}
