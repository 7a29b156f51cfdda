//! `sim-core`: the geometry and physics of dynamic point-set surfaces.
//!
//! Contract: pure computation. No I/O, no clocks, no global state; time enters as arguments.
//! File formats are parsed from and written to caller-supplied readers and writers.
//!
//! The point-set surface (DESIGN §2), stage by stage:
//! [`knn::PointIndex`] and [`knn::KnnGraph`] → [`normals`] (PCA, MST orientation) →
//! [`field::GlobalField::build`] (per-point [`local_fit`] B-spline fields, blended; for a
//! static surface optionally at a thinned subset of the points, `FitParams::centre_spacing`,
//! plus [`gaps`] fields centred in the gaps one-sided neighbourhoods face) →
//! queries `value`, `value_and_gradient`, `project_to_zero_set`, and `is_trusted` (the zero set
//! is only evidence of a surface near the points: meshing, projection, region grids and CSG
//! classification all ignore it elsewhere); [`mesh`] extracts the trusted zero set, evaluating
//! only the [`sparse`] blocks near the points; [`reconstruct`] runs all stages; [`sampling`]
//! makes analytic test shapes with exact signed distances; [`accuracy`] measures a surface
//! against a reference both ways (spurious pieces and holes); [`io`] reads and writes PLY, OFF,
//! OBJ, XYZ/PWN and STL.
//!
//! Haptic rendering (DESIGN §4–5): [`haptic`] (Kim-style field force with a virtual contact
//! point, friction and damping; the local contact models the haptics server renders; the
//! sculpting reaction), [`probe`] (the shaped ellipsoid probe of seed 004) and
//! [`bspline_surface`] (a B-spline patch with its mass-spring dual, sculpted by the probe).
//!
//! Dynamic sculpting (DESIGN §3–4): [`grid`] (regular grids and the immutable [`grid::ScalarGrid`]
//! snapshots the haptic thread samples) → [`dynamics`] (the narrow-band mass-spring field and its
//! forward/symplectic/backward Euler steppers) → [`follow`] (points follow the zero set, local
//! fields are refitted) → [`scene`] (objects and the one simulated region); [`tools`] (rope,
//! painting, embossing), [`csg`] (Booleans with crease samples), [`resample`] (up/down-sampling).

pub mod accuracy;
pub mod bspline;
pub mod bspline_surface;
pub mod csg;
pub mod dynamics;
pub mod field;
pub mod follow;
pub mod gap_samples;
pub mod gaps;
pub mod grid;
pub mod haptic;
pub mod io;
pub mod knn;
pub mod linalg;
pub mod local_fit;
pub mod mesh;
pub mod normals;
pub mod outliers;
pub mod pointset;
pub mod probe;
pub mod projection;
pub mod reconstruct;
pub mod resample;
pub mod sampling;
pub mod scene;
pub mod sparse;
pub mod spatial;
pub mod tools;

pub use field::{FieldError, GlobalField, NoProgress, Progress};
pub use local_fit::FitParams;
pub use pointset::PointSet;
