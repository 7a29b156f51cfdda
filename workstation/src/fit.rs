//! `workstation fit`: fit a point set (a file or an analytic generator) into an implicit
//! surface, time each construction stage, measure the zero set against a reference and
//! optionally mesh it.
//!
//! Errors are relative to the reference size: the radius for an analytic sphere, the
//! bounding-box diagonal otherwise. The figure to judge a surface by is the two-sided one
//! (`surface`): the zero set is meshed at `--resolution` and sampled over its whole area against
//! the reference, and the reference against it, so spurious sheets and holes both count. The
//! projected figure (`projected_*`) only sees the zero set near the data. Timing uses the wall
//! clock around each sim-core stage and around meshing.

pub mod spec;

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use sim_core::accuracy::{
    Distances, ErrorBySpacing, MeshReference, Reference, SampledError, TwoSidedError,
    zero_set_error,
};
use sim_core::io::{self, Format, Loaded};
use sim_core::mesh::{CutPiece, MeshOptions, TriMesh, extract_zero_set_with};
use sim_core::reconstruct::{NormalPolicy, Stage, StageObserver, reconstruct};
use sim_core::sampling::Noise;
use sim_core::{FitParams, PointSet, Progress};

use spec::{InputSpec, ReferenceSpec, parse_input, parse_reference};

/// Mixed into `--seed` for the error samples, so they never coincide with generated input
/// points (which use `--seed` itself).
const ERROR_SEED_SALT: u64 = 0x9e37_79b9_7f4a_7c15;

/// Arguments of `workstation fit`.
#[derive(Debug, Clone, clap::Args)]
pub struct FitArgs {
    /// Point or mesh file (.ply .off .obj .xyz .pwn .stl), sample:MESH_FILE:N (N points on
    /// the mesh's triangles with interpolated normals: a dense scan), or a generator: gen:sphere:R:N,
    /// gen:torus:R:r:N, gen:ellipsoid:a:b:c:N, gen:box:hx:hy:hz:round:N,
    /// gen:cylinder:radius:height:N, gen:plate:side:thickness:N, gen:carved:R:r:d:N (sphere R
    /// minus sphere r at distance d: a CSG difference with a sharp crease).
    pub input: String,
    /// Ground truth: sphere:R, torus:R,r, ellipsoid:a,b,c, box:hx,hy,hz,round, cylinder:r,h,
    /// plate:side,t, carved:R,r,d, mesh:FILE or none. Default: the generator's shape, or the input file's own
    /// faces when it has any.
    #[arg(long)]
    pub reference: Option<String>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write the meshed zero set (.ply, .obj or .stl).
    #[arg(long, value_name = "OUT")]
    pub mesh: Option<PathBuf>,
    /// Write the fitted points with their normals (and colours) as binary PLY.
    #[arg(long, value_name = "OUT")]
    pub points_out: Option<PathBuf>,
    /// Neighbours per local fit (the point included).
    #[arg(long, default_value_t = FitParams::default().k)]
    pub k: usize,
    /// B-spline coefficients per axis (3..=6).
    #[arg(long, default_value_t = FitParams::default().size)]
    pub size: usize,
    /// Off-surface sample offset, relative to the neighbourhood radius.
    #[arg(long, default_value_t = FitParams::default().offset)]
    pub offset: f64,
    /// Row-weight width h, relative to the neighbourhood radius.
    #[arg(long, default_value_t = FitParams::default().weight_width)]
    pub weight_width: f64,
    /// Weight of each point's normal against its position in the local fits (1: equal, what a
    /// sculpting scene fits with). The default leans on positions: a mesh's vertex normals are
    /// averaged across its edges, and a fit that follows them fully bulges beside the edge.
    #[arg(long, default_value_t = FIT_NORMAL_WEIGHT)]
    pub normal_weight: f64,
    /// Tikhonov weight toward the planar field (relative). The default damps the ripple a
    /// 3×3×3 fit makes beside an edge or a rounding finer than the neighbourhood (CAD parts);
    /// 0.00001 is what a sculpting scene fits with, a little more accurate on smooth shapes.
    #[arg(long, default_value_t = FIT_REGULARIZATION)]
    pub regularization: f64,
    /// Radius of each local field's blending weight, relative to its domain's half-size
    /// (≤ 1 keeps the support inside the domain).
    #[arg(long, default_value_t = FitParams::default().support)]
    pub support: f64,
    /// Trust radius, relative to each point's support radius: the zero set farther than this
    /// from every point is where local fits extrapolate, and is not meshed or touched.
    #[arg(long, default_value_t = FitParams::default().trust)]
    pub trust: f64,
    /// Least total blending weight where the zero set is trusted (≈ 5 on a sampled surface;
    /// 0 turns the weight test off).
    #[arg(long, default_value_t = FitParams::default().trust_weight)]
    pub trust_weight: f64,
    /// Support radii off a point's tangent plane beyond which it disowns the zero set (fins
    /// beside creases; inf turns the test off).
    #[arg(long, default_value_t = FitParams::default().trust_plane)]
    pub trust_plane: f64,
    /// Mesh the zero set only where it faces the way its points do (`false`: also the backs
    /// of the bumps single noisy points make, which show as small detached pieces).
    #[arg(long, default_value_t = FitParams::default().trust_facing, action = clap::ArgAction::Set)]
    pub trust_facing: bool,
    /// Local fields at a thinned subset of the points: a point gets one only where no point
    /// already given one lies within this fraction (0..=1) of its neighbourhood radius; every
    /// fit still uses its k nearest of all the points, and the trust tests all the points. The
    /// default fits about half as many fields as points: 0.7–0.9 of the time, about the same
    /// RMS error (docs/BENCHMARKS.md, "Surfaces against MeshLab"). 0: a field at every point,
    /// the surface a sculpting scene uses (to measure that field's error).
    #[arg(long, default_value_t = FIT_CENTRE_SPACING)]
    pub centre_spacing: f64,
    /// With thinned centres: the spacing where the surface is flat (the neighbours face within
    /// 1.8° of the point, lie on its tangent plane within 0.5 % of their radius and surround it),
    /// which any local fit follows exactly with fewer fields; creases, rims and bends keep
    /// --centre-spacing. 0 (or not above --centre-spacing): the same spacing everywhere
    #[arg(long, default_value_t = FIT_FLAT_SPACING)]
    pub flat_spacing: f64,
    /// Gap fields (with thinned centres only): where a centre's neighbours lean to one side by
    /// at least this fraction of its neighbourhood radius and a point lies across the gap on
    /// the other side, one more local field is fitted in the gap (the place between them
    /// clearest of the points) to that place's own k nearest points, so the gap is bridged from
    /// all sides, not by the one-sided fits around it (which sag or bulge: a face sampled only
    /// along its edges). 0: none, the library's default
    #[arg(long, default_value_t = FIT_GAP_FIELDS)]
    pub gap_fields: f64,
    /// With thinned centres: a point fits to only its k-even nearest where they surround it
    /// evenly (see --even-lean) and face within 90° of it, so the fit follows the detail
    /// they sample; else to the fewest beyond that which do, or to k (a rim, a gap, a crease).
    /// 0: k everywhere.
    #[arg(long, default_value_t = FIT_K_EVEN)]
    pub k_even: usize,
    /// How far the k-even nearest's mean offset along the point's tangent plane may lean,
    /// relative to their radius, for them to count as surrounding it.
    #[arg(long, default_value_t = FIT_EVEN_LEAN)]
    pub even_lean: f64,
    /// With thinned centres: each local field blends with less weight the worse its fit
    /// follows its own points, half its weight where their RMS misfit is this fraction of its
    /// domain's half edge, so a fit that cannot follow them (two sheets meeting in a corner
    /// tighter than its domain, as at the corner of a mouth) gives way to its neighbours'. The
    /// fits' median misfit is 0–2 % of the half edge. 0: every field weighs the same
    #[arg(long, default_value_t = FIT_MISFIT_WIDTH)]
    pub misfit_width: f64,
    /// With thinned centres: in each gap among the points at least this fraction (0..1) of the
    /// nearest point's neighbourhood radius wide, one sample on the sphere APSS would fit there
    /// joins the points, so the fits around it follow the surface across the gap instead of
    /// carrying their side's curvature over it (a CAD face between far-apart vertices, a scan's
    /// sparse band); the points alone still decide where the surface is trusted. 0.3 is the
    /// measured setting: more accurate than the default on most shapes, slower
    /// (docs/BENCHMARKS.md, "Gap samples"). 0: none
    #[arg(long, default_value_t = FIT_GAP_SAMPLES)]
    pub gap_samples: f64,
    /// Sharp creases (CAD data): move mesh vertices near a crease of two faces onto the faces'
    /// planes and the crease line where a wedge of two planes explains the points there. It
    /// also sharpens a rounding smaller than the point spacing, so it is off by default.
    #[arg(long)]
    pub creases: bool,
    /// Leave mesh vertices at the mean of their cell's edge crossings (plain surface nets)
    /// instead of projecting them onto the zero set: to measure what the projection gains.
    #[arg(long)]
    pub unprojected_vertices: bool,
    /// Keep mesh pieces that no input point supports (none holds a point's nearest vertex).
    /// By default they are cut, and the report lists each with its size and its distance from
    /// the nearest point: the trusted zero set should leave none, so one cut is worth a look.
    #[arg(long)]
    pub keep_unsupported_pieces: bool,
    /// What to do with given normals: keep, reorient (fix flipped ones) or estimate (ignore).
    #[arg(long, value_enum, default_value_t = NormalsArg::Keep)]
    pub normals: NormalsArg,
    /// Points projected onto the zero set for the projected error (0: skip it).
    #[arg(long, default_value_t = 10_000)]
    pub error_samples: usize,
    /// Samples on each side for the two-sided surface error: on the meshed zero set against the
    /// reference, and on the reference against the mesh (0: skip it, and skip meshing unless
    /// --mesh asks for it).
    #[arg(long, default_value_t = 100_000)]
    pub surface_samples: usize,
    /// Seed of the generator and of the error samples.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Gaussian position noise for generated input, relative to the reference size.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Grid cells along the longest side of the points' bounding box, for --mesh and the surface
    /// error (8..=1024; the grid extends a few cells beyond the box at the same spacing).
    #[arg(long, default_value_t = 128)]
    pub resolution: usize,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `--normals`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NormalsArg {
    /// Keep given normals (a mesh without normals: from its faces); estimate only missing ones.
    /// Normals whose signs look like noise (unoriented, as some scanners write them) are made
    /// consistent first, with a warning.
    Keep,
    /// Make given normals' signs consistent (repairs flipped normals).
    Reorient,
    /// Ignore given normals; PCA + MST orientation.
    Estimate,
}

/// What `fit` measured; printed as text or as one JSON object.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// Input as given.
    pub input: String,
    /// Number of points fitted.
    pub points: usize,
    /// Total construction time (k-NN + normals + fits), seconds.
    pub construct_s: f64,
    /// k-d tree and k-NN queries, seconds.
    pub knn_s: f64,
    /// Normal estimation / orientation, seconds.
    pub normals_s: f64,
    /// Local fits and the support index, seconds.
    pub fits_s: f64,
    /// Worker threads used.
    pub threads: usize,
    /// Peak resident memory of the process when construction ended (input, points and
    /// field), MiB (Linux `VmHWM`; 0 elsewhere).
    pub peak_rss_mib: f64,
    /// Normals estimated by PCA.
    pub estimated_normals: usize,
    /// Points rejected as outliers.
    pub outliers: usize,
    /// Local fields fitted (fewer than the points when thinned: `params.centre_spacing`), gap
    /// fields included.
    pub local_fields: usize,
    /// Of those, gap fields (`params.gap_fields`): centred between points, not at one.
    pub gap_fields: usize,
    /// Points fitting to fewer than k neighbours, their nearest surrounding them evenly
    /// (`params.k_even`).
    pub small_neighbourhoods: usize,
    /// Gap samples that joined the points (`params.gap_samples`).
    pub gap_samples: usize,
    /// The reference measured against, if any.
    pub reference: Option<String>,
    /// Length the relative errors are divided by.
    pub reference_size: Option<f64>,
    /// Two-sided error of the meshed zero set, relative to `reference_size`.
    pub surface: Option<SurfaceError>,
    /// RMS distance to the reference of points projected onto the zero set from near the
    /// reference, relative to `reference_size` (blind to zero-set pieces away from the data).
    pub projected_rms_error: Option<f64>,
    /// Max of the same, relative.
    pub projected_max_error: Option<f64>,
    /// Projected RMS in metres.
    pub projected_rms_error_abs: Option<f64>,
    /// Projected max in metres.
    pub projected_max_error_abs: Option<f64>,
    /// Points projected for the projected error.
    pub error_samples: usize,
    /// Projections that did not converge (still counted).
    pub unconverged: usize,
    /// Error measurement time, seconds.
    pub measure_s: f64,
    /// The fit parameters.
    pub params: FitParams,
    /// Triangles of the meshed zero set (written with --mesh).
    pub mesh_triangles: Option<usize>,
    /// Meshing wall time, seconds (also when only the surface error needed the mesh).
    pub mesh_s: Option<f64>,
    /// Grid-node field evaluations meshing made (probes of the blocks near the points, nodes of
    /// those that can hold the surface), and the node count of the whole box at that
    /// resolution (what dense meshing would evaluate).
    pub mesh_evaluations: Option<[usize; 2]>,
    /// Where meshing's time went (processor seconds per phase) and how many Newton
    /// projections it made.
    pub mesh_profile: Option<MeshProfile>,
    /// Grid cells along the longest side of the points' box.
    pub resolution: usize,
}

/// [`sim_core::mesh::MeshStats`]' time and projection counts, for the report.
#[derive(Debug, Clone, Serialize)]
pub struct MeshProfile {
    /// Per phase, s.
    pub timings: sim_core::mesh::MeshTimings,
    /// Cells the walk along the zero set visited.
    pub cells_visited: usize,
    /// Connected components of the mesh, and the triangles of each (largest first; at most
    /// 20 listed).
    pub components: usize,
    pub component_triangles: Vec<usize>,
    /// Edges one triangle alone uses (vertices at one position merged): the rims of holes and
    /// of open surfaces, 0 for a closed one. A part thinner than about 1.5 cells shows here.
    pub open_edges: usize,
    /// Vertices of trusted cells projected onto the zero set.
    pub projections: usize,
    /// Newton steps those took.
    pub newton_steps: usize,
    /// Projected vertices left out because the zero set there faces against its points.
    pub inverted: usize,
    /// Vertices moved onto the wedge of a crease's two faces.
    pub sharpened: usize,
    /// Pieces cut because no input point supports them (`--keep-unsupported-pieces` keeps
    /// them); `components` and the written mesh are what is left.
    pub cut_pieces: Vec<CutPiece>,
}

/// The two-sided error, relative to the reference size (see
/// [`sim_core::accuracy::mesh_error`]).
#[derive(Debug, Clone, Serialize)]
pub struct SurfaceError {
    /// Samples on each side.
    pub samples: usize,
    /// Mesh → reference: spurious pieces show here.
    pub to_reference: Distances,
    /// Reference → mesh: holes show here.
    pub coverage: Distances,
    /// Both ways by distance from the nearest input point (as `mesh-error --points`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub by_spacing: Option<ErrorBySpacing>,
}

impl SurfaceError {
    /// The relative form of a [`TwoSidedError`].
    pub fn relative(e: &TwoSidedError) -> Self {
        let (to_reference, coverage) = e.relative();
        Self {
            samples: e.samples,
            to_reference,
            coverage,
            by_spacing: None,
        }
    }
}

struct Timer {
    started: Option<Instant>,
    spent: [Duration; 3],
}

impl StageObserver for Timer {
    fn begin(&mut self, _: Stage) {
        self.started = Some(Instant::now());
    }
    fn end(&mut self, stage: Stage) {
        let spent = self.started.take().map_or(Duration::ZERO, |t| t.elapsed());
        self.spent[stage as usize] += spent;
    }
}

/// A progress bar as the fit's progress sink.
pub(crate) struct Bar(pub(crate) ProgressBar);

impl Progress for Bar {
    fn advance(&self, n: usize) {
        self.0.inc(n as u64);
    }
}

fn format_of(path: &Path) -> anyhow::Result<Format> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    Format::from_extension(ext).with_context(|| {
        format!(
            "{}: unknown extension (ply, off, obj, xyz, pwn, stl)",
            path.display()
        )
    })
}

fn read_file(path: &Path) -> anyhow::Result<Loaded> {
    let format = format_of(path)?;
    let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
    io::read(BufReader::new(file), format).with_context(|| format!("reading {}", path.display()))
}

/// A reference mesh file, indexed for distance queries.
fn read_mesh_reference(path: &Path) -> anyhow::Result<MeshReference> {
    let mesh = read_file(path)?
        .mesh
        .with_context(|| format!("{} has no faces", path.display()))?;
    MeshReference::new(mesh).context("reference mesh has no triangles")
}

/// One direction of a two-sided error, as the text reports print it.
fn distances_text(x: &Distances) -> String {
    format!("RMS {:.3e}, p99 {:.3e}, max {:.3e}", x.rms, x.p99, x.max)
}

fn write_mesh(path: &Path, mesh: &TriMesh) -> anyhow::Result<()> {
    let format = format_of(path)?;
    if !matches!(format, Format::Ply | Format::Obj | Format::Stl) {
        bail!(
            "{}: meshes are written as .ply, .obj or .stl",
            path.display()
        );
    }
    let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
    io::write_mesh(BufWriter::new(file), mesh, format)
        .with_context(|| format!("writing {}", path.display()))
}

/// `fit`'s default [`FitParams::centre_spacing`]. On the eleven MeshLab comparison shapes at
/// resolution 200, 0.35 against a field at every point: 0.7–0.9 of the time, RMS from 4 %
/// worse to 43 % better (the CSG crease), the max up to 23 % larger, one piece each; 0.25 left
/// a two-triangle piece on the CSG crease, and 0.5 split three shapes and grew the errors.
const FIT_CENTRE_SPACING: f64 = 0.35;

/// `fit`'s default [`FitParams::flat_spacing`] (the library's is 0: off). At resolution 200
/// against 0: the thin plate 8,093 fields instead of 10,853, the rounded box 8,156 instead of
/// 10,886, the fandisk 5,378 instead of 6,159, their errors within 2 % (the plate's coverage
/// max 6 %); the scans and curved shapes unchanged, bit for bit. 0.6 opened a hole in a slab
/// two cells thick on a coarse grid (`parts_two_to_three_cells_thick_mesh_whole_on_a_coarse_grid`)
/// (docs/BENCHMARKS.md, "Flat faces").
const FIT_FLAT_SPACING: f64 = 0.5;

/// `fit`'s default [`FitParams::gap_fields`] (the library's is 0: none). On the MeshLab
/// comparison shapes (resolution 200, the other defaults) against none: the rocker arm's RMS
/// 13 % lower and its max 9 %, the thin plate's max 17 %; the torus's max 30 % higher (still
/// 0.35× APSS's), the bunny scan's RMS 3 %; the rest within 2 %, one piece each; about 5 % of
/// the time (docs/BENCHMARKS.md, "Gap fields").
const FIT_GAP_FIELDS: f64 = 0.12;

/// `fit`'s default [`FitParams::k_even`] and [`FitParams::even_lean`] (the library's: off). On
/// the MeshLab comparison shapes (resolution 200, the other defaults) against k = 20 at every
/// point: the armadillo's RMS and coverage 14 % lower, homer's 4 %, the fandisk's max 13 %,
/// the rocker arm's max 5 %; homer's max 2 % higher; one piece each (docs/BENCHMARKS.md,
/// "Smaller neighbourhoods"). 14 at every point opened holes in the randomly sampled shapes;
/// without the 90° guard the cow's thin tail came out in pieces.
const FIT_K_EVEN: usize = 16;
const FIT_EVEN_LEAN: f64 = 0.2;

/// `fit`'s default [`FitParams::misfit_width`] (the library's is 0: every field weighs the
/// same). On the MeshLab comparison shapes (resolution 200, the other defaults) against 0:
/// homer's max 22 % lower (its worst spot, the corner of the mouth, is gone), the rocker
/// arm's 3 %; cheburashka's RMS 4 % higher (still ahead of APSS); the rest within 2.5 %, one
/// piece each (docs/BENCHMARKS.md, "Fits weighed by their misfit"). 0.01 also lowers the
/// rocker arm's max 11 % but raises the bunny's 18 %.
const FIT_MISFIT_WIDTH: f64 = 0.035;

/// Cut the pieces of `mesh` that no point of `points` supports
/// ([`TriMesh::cut_unsupported_pieces`]), each logged as a warning, and return them. The
/// trusted zero set should leave none, so every meshing command runs this net and says what
/// it caught.
pub fn cut_unsupported_pieces(mesh: &mut TriMesh, points: &[DVec3]) -> Vec<CutPiece> {
    let cut = mesh.cut_unsupported_pieces(points);
    for piece in &cut {
        let [x, y, z] = piece.centre;
        tracing::warn!(
            "cut a mesh piece no point supports: {} triangles at ({x:.4}, {y:.4}, {z:.4}), \
             {:.3e} from the nearest point",
            piece.triangles,
            piece.distance
        );
    }
    cut
}

/// `fit`'s default [`FitParams::gap_samples`]: none, as in the library. On the MeshLab
/// comparison shapes (resolution 200, the other defaults), 0.3 puts 1 of the 42 error figures
/// behind APSS's instead of 6 (the rocker arm's RMS 1.18 → 0.996 and max 1.24 → 0.97, homer's
/// RMS 1.08 → 0.95 and coverage 1.10 → 0.96, the bunny scan's coverage 1.13 → 0.98; the one
/// left is the fandisk's max, 1.17 → 1.10), with one piece on every shape, but takes up to
/// twice as long to construct (the airplane 1.3× APSS's wall time in the same run, 0.8×
/// without), so it is not on by default (docs/BENCHMARKS.md, "Gap samples").
const FIT_GAP_SAMPLES: f64 = 0.0;

/// `fit`'s default [`FitParams::regularization`], 30× the library's. On the MeshLab comparison
/// shapes (resolution 200, thinned centres) against 1e-5: RMS 23 % lower on the rounded box,
/// 21 % on the thin plate, 12 % on the rocker arm, 14 % on the fandisk, the same on the scans
/// and the CSG crease, 37 % higher on the torus (still a third of APSS's error there). 1e-4
/// keeps the torus nearer (1.2×) but the plate's max at 1.4× this one's; 1e-3 puts the torus
/// at 1.9×.
const FIT_REGULARIZATION: f64 = 3e-4;

/// `fit`'s default [`FitParams::normal_weight`], a quarter of the library's. On the MeshLab
/// comparison shapes (resolution 200, the other defaults) against 1: the thin plate's max 21 %
/// lower and the rocker arm's 16 %, the rounded box's coverage RMS 9 % lower, RMS 12 % lower on
/// the fandisk, 5 % on the rounded box, 4 % on the rocker arm, 3 % on the bunny; 4 % higher on
/// the torus (still 0.4× APSS's) and 5 % on the face range map; the others within 2 %, one
/// piece each. 0.5 gains about half as much; 0.1 a little more on the CAD parts, but the
/// bunny's max grows.
const FIT_NORMAL_WEIGHT: f64 = 0.25;

/// Run `fit` and return the report (printing is the caller's choice; see [`print()`]).
pub fn run(args: &FitArgs) -> anyhow::Result<FitReport> {
    anyhow::ensure!(
        args.surface_samples <= MAX_SURFACE_SAMPLES,
        "--surface-samples must be at most {MAX_SURFACE_SAMPLES} (got {})",
        args.surface_samples
    );
    crate::cap!(
        "--error-samples",
        args.error_samples,
        MAX_SURFACE_SAMPLES,
        "samples"
    )?;
    anyhow::ensure!(
        args.noise.is_finite() && args.noise >= 0.0,
        "--noise must be finite and ≥ 0 (got {})",
        args.noise
    );
    let input = parse_input(&args.input)?;
    let (points, own_mesh, default_ref): (PointSet, Option<TriMesh>, ReferenceSpec) = match &input {
        InputSpec::File(path) => {
            let mut loaded = read_file(path)?;
            // `--normals estimate` still ignores these; with `keep`, unoriented ones are made
            // consistent by the fit (`NormalPolicy::KeepConsistent`, on its k-NN graph).
            loaded.normals_from_winding();
            (loaded.points, loaded.mesh, ReferenceSpec::None)
        }
        InputSpec::SampledMesh { path, n } => {
            let mesh = read_file(path)?
                .mesh
                .with_context(|| format!("{} has no faces to sample", path.display()))?;
            let points = crate::bigscan::sample_mesh(&mesh, *n, args.seed, None);
            anyhow::ensure!(!points.is_empty(), "{} has no area", path.display());
            (points, Some(mesh), ReferenceSpec::None)
        }
        InputSpec::Generated { shape, n } => {
            let noise = Noise {
                position: args.noise * shape.reference_size(),
                normal: 0.0,
            };
            (
                shape.sample_noisy(*n, args.seed, noise),
                None,
                ReferenceSpec::Shape(*shape),
            )
        }
    };
    let reference_spec = match &args.reference {
        Some(s) => parse_reference(s)?,
        None => default_ref,
    };
    // A file with faces is measured against its own mesh unless a reference is given.
    let own_reference = match (&args.reference, own_mesh) {
        (None, Some(mesh)) => MeshReference::new(mesh),
        _ => None,
    };
    let reference: Option<(String, Box<dyn Reference>)> = match reference_spec {
        ReferenceSpec::None => {
            own_reference.map(|m| ("input mesh".to_string(), Box::new(m) as Box<dyn Reference>))
        }
        ReferenceSpec::Shape(shape) => Some((format!("{shape:?}"), Box::new(shape))),
        ReferenceSpec::Mesh(path) => Some((
            format!("mesh {}", path.display()),
            Box::new(read_mesh_reference(&path)?),
        )),
    };
    let params = FitParams {
        k: args.k,
        size: args.size,
        offset: args.offset,
        weight_width: args.weight_width,
        normal_weight: args.normal_weight,
        regularization: args.regularization,
        support: args.support,
        trust: args.trust,
        trust_weight: args.trust_weight,
        trust_plane: args.trust_plane,
        trust_facing: args.trust_facing,
        centre_spacing: args.centre_spacing,
        flat_spacing: args.flat_spacing,
        gap_fields: args.gap_fields,
        k_even: args.k_even,
        even_lean: args.even_lean,
        misfit_width: args.misfit_width,
        gap_samples: args.gap_samples,
        ..FitParams::default()
    };
    let policy = match args.normals {
        NormalsArg::Keep => NormalPolicy::KeepConsistent,
        NormalsArg::Reorient => NormalPolicy::Reorient,
        NormalsArg::Estimate => NormalPolicy::Estimate,
    };
    let bar = if args.quiet || args.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(points.len() as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("fitting {bar:40} {pos}/{len} local fields ({per_sec})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut timer = Timer {
        started: None,
        spent: [Duration::ZERO; 3],
    };
    let t0 = Instant::now();
    let rec = reconstruct(&points, &params, policy, &mut timer, &Bar(bar.clone()))?;
    let construct_s = t0.elapsed().as_secs_f64();
    if let Some(share) = rec.reoriented {
        crate::sculpt::warn_reoriented(&args.input, share);
    }
    let peak_rss_mib = crate::bigscan::peak_rss_kib() as f64 / 1024.0;
    bar.finish_and_clear();

    let t1 = Instant::now();
    let error = reference
        .as_ref()
        .filter(|_| args.error_samples > 0)
        .map(|(_, r)| {
            zero_set_error(
                &rec.field,
                r.as_ref(),
                args.error_samples,
                0.5,
                args.seed ^ ERROR_SEED_SALT,
            )
        });
    let measure_s = t1.elapsed().as_secs_f64();

    let want_surface = reference.is_some() && args.surface_samples > 0;
    let (mut mesh_triangles, mut mesh_s, mut surface) = (None, None, None);
    let (mut mesh_evaluations, mut mesh_profile) = (None, None);
    if args.mesh.is_some() || want_surface {
        let t2 = Instant::now();
        let (lo, hi) = points.bounds().context("no points")?;
        let pad = DVec3::splat(0.05 * (hi - lo).length() + 2.0 * rec.field.scale());
        // `--resolution` counts cells across the points' box (as other tools do); the grid
        // extends past it by the padding at the same spacing.
        let cells = args.resolution.clamp(8, 1024) as f64;
        let padded = ((hi - lo + 2.0 * pad).max_element() / (hi - lo).max_element() * cells).ceil();
        let box_ = (lo - pad, hi + pad);
        let options = MeshOptions {
            creases: args.creases,
            unprojected: args.unprojected_vertices,
        };
        let (mut mesh, stats) = extract_zero_set_with(&rec.field, box_, padded as usize, &options);
        let cut_pieces = if args.keep_unsupported_pieces {
            Vec::new()
        } else {
            cut_unsupported_pieces(&mut mesh, &points.positions)
        };
        mesh_s = Some(t2.elapsed().as_secs_f64());
        mesh_evaluations = Some([stats.evaluations, stats.box_nodes]);
        // The census (both passes over every edge) runs beside the file's writing.
        let (written, ((_, sizes), open_edges)) = rayon::join(
            || {
                args.mesh
                    .as_ref()
                    .map_or(Ok(()), |out| write_mesh(out, &mesh))
            },
            || rayon::join(|| mesh.components(), || mesh.open_edges()),
        );
        written?;
        mesh_profile = Some(MeshProfile {
            timings: stats.timings,
            cells_visited: stats.cells_visited,
            components: sizes.len(),
            component_triangles: sizes.iter().copied().take(20).collect(),
            open_edges,
            projections: stats.projections,
            newton_steps: stats.newton_steps,
            inverted: stats.inverted,
            sharpened: stats.sharpened,
            cut_pieces,
        });
        mesh_triangles = Some(mesh.triangles.len());
        if let Some((_, r)) = reference.as_ref().filter(|_| want_surface) {
            let sampled = SampledError::new(
                &mesh,
                r.as_ref(),
                args.surface_samples,
                args.seed ^ ERROR_SEED_SALT,
            )
            .context("the meshed zero set is empty: nothing to measure against the reference")?;
            surface = Some(SurfaceError {
                by_spacing: sampled.by_spacing(&points.positions),
                ..SurfaceError::relative(&sampled.summary())
            });
        }
    }
    if let Some(out) = &args.points_out {
        let fitted = PointSet {
            normals: Some(rec.normals.clone()),
            ..points.clone()
        };
        let file = File::create(out).with_context(|| format!("creating {}", out.display()))?;
        io::write_points_ply(BufWriter::new(file), &fitted, false)?;
    }
    let secs = |s: Stage| timer.spent[s as usize].as_secs_f64();
    Ok(FitReport {
        input: args.input.clone(),
        points: points.len(),
        construct_s,
        knn_s: secs(Stage::Knn),
        normals_s: secs(Stage::Normals),
        fits_s: secs(Stage::Fit),
        threads: rayon::current_num_threads(),
        peak_rss_mib,
        estimated_normals: rec.estimated_normals,
        outliers: rec.field.outlier_count(),
        local_fields: rec.field.len(),
        gap_fields: rec.field.gap_field_count(),
        small_neighbourhoods: rec.field.small_neighbourhood_count(),
        gap_samples: rec.field.gap_sample_count(),
        reference: reference.as_ref().map(|(name, _)| name.clone()),
        reference_size: reference.as_ref().map(|(_, r)| r.size()),
        surface,
        projected_rms_error: error.map(|e| e.rms_relative()),
        projected_max_error: error.map(|e| e.max_relative()),
        projected_rms_error_abs: error.map(|e| e.rms),
        projected_max_error_abs: error.map(|e| e.max),
        error_samples: error.map_or(0, |e| e.samples),
        unconverged: error.map_or(0, |e| e.unconverged),
        measure_s,
        params,
        mesh_triangles,
        mesh_s,
        mesh_evaluations,
        mesh_profile,
        resolution: args.resolution,
    })
}

/// Print the report as text, or as one JSON object with `--json`.
pub fn print(report: &FitReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string(report)?);
        return Ok(());
    }
    let r = report;
    println!("input        {}", r.input);
    println!(
        "points       {} ({} normals estimated, {} outliers rejected)",
        r.points, r.estimated_normals, r.outliers
    );
    println!(
        "params       k = {}, size = {}³, offset = {}, threads = {}",
        r.params.k, r.params.size, r.params.offset, r.threads
    );
    println!(
        "fields       {} local fields (centre spacing {}{}; {} of them gap fields)",
        r.local_fields,
        r.params.centre_spacing,
        r.params
            .flat_thinning()
            .map_or(String::new(), |flat| format!(", {flat} where flat")),
        r.gap_fields
    );
    if r.params.k_even > 0 {
        println!(
            "neighbours   {} points fit to {}–{} (their nearest surround them), the rest to {}",
            r.small_neighbourhoods,
            r.params.k_even,
            r.params.k - 1,
            r.params.k
        );
    }
    if r.params.gap_samples > 0.0 {
        println!(
            "gap samples  {} (in gaps ≥ {} of a neighbourhood radius wide)",
            r.gap_samples, r.params.gap_samples
        );
    }
    println!("k-NN         {:9.4} s", r.knn_s);
    println!("normals      {:9.4} s", r.normals_s);
    println!("fits         {:9.4} s", r.fits_s);
    println!("construction {:9.4} s total", r.construct_s);
    println!("memory       {:9.1} MiB peak resident", r.peak_rss_mib);
    match (&r.reference, r.reference_size) {
        (Some(name), Some(size)) => println!("reference    {name} (size {size:.6e} m)"),
        _ => println!("reference    none given (use --reference sphere:R | torus:R,r | mesh:FILE)"),
    }
    if let (Some(t), Some(s)) = (r.mesh_triangles, r.mesh_s) {
        println!(
            "mesh         {t} triangles at resolution {} in {s:.4} s",
            r.resolution
        );
    }
    if let Some([sparse, dense]) = r.mesh_evaluations {
        println!(
            "             {sparse} field evaluations ({:.1} % of the box's {dense} nodes)",
            100.0 * sparse as f64 / dense.max(1) as f64
        );
    }
    if let Some(p) = &r.mesh_profile {
        let t = &p.timings;
        println!(
            "             {} connected component(s){}{}, {} open edge(s){}",
            p.components,
            if p.cut_pieces.is_empty() {
                String::new()
            } else {
                format!(
                    " after {} piece(s) no point supports were cut (logged above)",
                    p.cut_pieces.len()
                )
            },
            if p.components > 1 {
                format!(" (triangles {:?})", p.component_triangles)
            } else {
                String::new()
            },
            p.open_edges,
            if p.open_edges > 0 {
                " (rims of holes or of an open surface; a part thinner than ~1.5 cells loses \
                 triangles: raise --resolution)"
            } else {
                ""
            }
        );
        println!(
            "             walk {:.3} s wall over {} cells; processor s: gather {:.3}, sample \
             {:.3}, cells {:.3}, trust {:.3}, project {:.3} ({} projections, {:.2} Newton steps \
             each, {} left out as facing against their points, {} moved onto creases); stitch \
             {:.3} (wall)",
            t.follow_s,
            p.cells_visited,
            t.gather_s,
            t.sample_s,
            t.cells_s,
            t.trust_s,
            t.project_s,
            p.projections,
            p.newton_steps as f64 / p.projections.max(1) as f64,
            p.inverted,
            p.sharpened,
            t.stitch_s,
        );
    }
    if let Some(e) = &r.surface {
        let d = distances_text;
        println!(
            "surface      mesh → reference   {} ({} samples each way, max also over every vertex; relative to the reference size)",
            d(&e.to_reference),
            e.samples
        );
        println!(
            "             reference → mesh   {} (coverage)",
            d(&e.coverage)
        );
        if let Some(by) = &e.by_spacing {
            print_by_spacing(by);
        }
    }
    if let (Some(rms), Some(max)) = (r.projected_rms_error, r.projected_max_error) {
        println!(
            "projected    RMS {rms:.3e}, max {max:.3e} over {} points projected from near the reference ({} unconverged)",
            r.error_samples, r.unconverged
        );
    }
    Ok(())
}

/// Arguments of `workstation mesh-error`.
#[derive(Debug, Clone, clap::Args)]
pub struct MeshErrorArgs {
    /// The mesh to measure (.ply .obj .off .stl), e.g. the output of `fit --mesh` or of another
    /// reconstruction tool.
    pub mesh: PathBuf,
    /// Ground truth, as for `fit --reference`: sphere:R, torus:R,r, box:hx,hy,hz,round,
    /// plate:side,t, carved:R,r,d, …, or mesh:FILE.
    #[arg(long)]
    pub reference: String,
    /// Samples on each side (on the mesh, on the reference), area-uniform: RMS and p99 are
    /// theirs. Each side's max also takes every vertex (the mesh's; a mesh reference's), so a
    /// spike or a hole narrower than the samples' spacing still shows.
    #[arg(long, default_value_t = 100_000)]
    pub samples: usize,
    /// Seed of the samples.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The points the mesh was made from (.ply .obj .off .xyz .stl; their vertices): break the
    /// error down by how far each sample lies from the nearest of them, in their median
    /// spacing. Error that grows between the points, not at them, is the method's interpolant.
    #[arg(long, value_name = "FILE")]
    pub points: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// What `mesh-error` measured: the same two-sided figure `fit` reports as `surface`.
#[derive(Debug, Clone, Serialize)]
pub struct MeshErrorReport {
    /// The mesh measured.
    pub mesh: String,
    /// The reference.
    pub reference: String,
    /// Length the relative figures are divided by.
    pub reference_size: f64,
    /// Samples on each side.
    pub samples: usize,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Connected pieces of the mesh (vertices at the same position merged).
    pub pieces: usize,
    /// Connected pieces of the reference, when it is a mesh.
    pub reference_pieces: Option<usize>,
    /// Edges of the mesh that one triangle alone uses (vertices at the same position merged):
    /// the rims of its holes and open borders.
    pub open_edges: usize,
    /// The same of the reference, when it is a mesh.
    pub reference_open_edges: Option<usize>,
    /// Mesh → reference, relative.
    pub to_reference: Distances,
    /// Reference → mesh (coverage), relative.
    pub coverage: Distances,
    /// With `--points`: both directions by distance from the nearest point.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub by_spacing: Option<ErrorBySpacing>,
}

/// Largest `--samples` of `mesh-error` (and `--surface-samples` and `--error-samples` of `fit`):
/// 10⁷ per side.
pub const MAX_SURFACE_SAMPLES: usize = 10_000_000;

/// Run `mesh-error`.
pub fn run_mesh_error(args: &MeshErrorArgs) -> anyhow::Result<MeshErrorReport> {
    anyhow::ensure!(
        (1..=MAX_SURFACE_SAMPLES).contains(&args.samples),
        "--samples must be in 1..={MAX_SURFACE_SAMPLES} (got {})",
        args.samples
    );
    let mesh = read_file(&args.mesh)?
        .mesh
        .with_context(|| format!("{} has no faces", args.mesh.display()))?;
    let (mut reference_pieces, mut reference_open_edges) = (None, None);
    let reference: Box<dyn Reference> = match parse_reference(&args.reference)? {
        ReferenceSpec::None => bail!("--reference none: mesh-error needs a reference"),
        ReferenceSpec::Shape(shape) => Box::new(shape),
        ReferenceSpec::Mesh(path) => {
            let truth = read_file(&path)?
                .mesh
                .with_context(|| format!("{} has no faces", path.display()))?;
            reference_pieces = Some(truth.pieces());
            reference_open_edges = Some(truth.open_edges());
            Box::new(MeshReference::new(truth).context("reference mesh has no triangles")?)
        }
    };
    // Read before the sampling, so a bad points file fails fast.
    let points = args
        .points
        .as_ref()
        .map(|path| read_file(path).map(|l| (path, l.points.positions)))
        .transpose()?;
    let seed = args.seed ^ ERROR_SEED_SALT; // as `fit` salts its own: same seed, same samples
    let sampled =
        SampledError::new(&mesh, reference.as_ref(), args.samples, seed).with_context(|| {
            format!(
                "{}: the mesh has no triangle of positive area",
                args.mesh.display()
            )
        })?;
    let by_spacing = match points {
        Some((path, points)) => Some(sampled.by_spacing(&points).with_context(|| {
            format!(
                "{}: needs two distinct points to measure a spacing",
                path.display()
            )
        })?),
        None => None,
    };
    let e = sampled.summary();
    let (to_reference, coverage) = e.relative();
    Ok(MeshErrorReport {
        mesh: args.mesh.display().to_string(),
        reference: args.reference.clone(),
        reference_size: e.reference_size,
        samples: e.samples,
        triangles: mesh.triangles.len(),
        pieces: mesh.pieces(),
        reference_pieces,
        open_edges: mesh.open_edges(),
        reference_open_edges,
        to_reference,
        coverage,
        by_spacing,
    })
}

/// Print a [`MeshErrorReport`] as text, or as one JSON object with `json`.
pub fn print_mesh_error(r: &MeshErrorReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string(r)?);
        return Ok(());
    }
    let d = distances_text;
    println!(
        "mesh         {} ({} triangles, {} connected piece(s), {} open edge(s))",
        r.mesh, r.triangles, r.pieces, r.open_edges
    );
    println!(
        "reference    {} (size {:.6e} m{})",
        r.reference,
        r.reference_size,
        r.reference_pieces
            .zip(r.reference_open_edges)
            .map_or(String::new(), |(n, e)| format!(
                ", {n} connected piece(s), {e} open edge(s)"
            ))
    );
    println!(
        "mesh → ref   {} ({} samples each way, max also over every vertex; relative to the size)",
        d(&r.to_reference),
        r.samples
    );
    println!("ref → mesh   {} (coverage)", d(&r.coverage));
    if let Some(by) = &r.by_spacing {
        print_by_spacing(by);
    }
    Ok(())
}

/// The bands of an [`ErrorBySpacing`] as a table (`mesh-error --points`, `fit --reference`).
fn print_by_spacing(by: &ErrorBySpacing) {
    println!(
        "by distance from the nearest point, in its median spacing ({:.4e} m):",
        by.spacing
    );
    println!("  spacings    mesh → ref                      ref → mesh (coverage)");
    println!("              samples  RMS        sq. error    samples  RMS        sq. error");
    for b in &by.bands {
        let band = match b.to {
            Some(to) => format!("{:.1}–{:.1}", b.from, to),
            None => format!("≥ {:.1}", b.from),
        };
        let side = |e: &sim_core::accuracy::BandError| {
            // An empty band has no RMS (the JSON's 0 is not an error of zero).
            let rms = if e.samples > 0.0 {
                format!("{:.3e}", e.rms)
            } else {
                "—".into()
            };
            format!(
                "{:>5.1} %  {rms:<8}  {:>5.1} %",
                100.0 * e.samples,
                100.0 * e.squared
            )
        };
        println!(
            "  {band:<10}  {}    {}",
            side(&b.to_reference),
            side(&b.coverage)
        );
    }
}

#[cfg(test)]
mod tests;
