//! `workstation sculpt SCRIPT.toml --out DIR`: run a scripted sculpting session headless
//! (objects, region, rope strokes, painting, embossing, CSG, resampling) and write every object
//! as PLY points (normals, colours) plus the meshed zero set, and `report.json`.
//!
//! The script format is in [`script`] and documented in `examples/sculpt/README.md`.

pub(crate) mod ops;
pub mod script;
#[cfg(test)]
mod tests;
mod validate;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use glam::DVec3;
use serde::Serialize;
use sim_core::dynamics::Integrator;
use sim_core::io::{self, Format};
use sim_core::mesh::extract_zero_set;
use sim_core::sampling::Shape;
use sim_core::scene::{RegionParams, ResampleOptions, Scene, SceneObject};
use sim_core::{FitParams, PointSet};

use script::{ObjectSpec, RegionSpec, Script};

/// Parsed arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct SculptArgs {
    /// The script (TOML).
    pub script: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// What one operation did.
#[derive(Debug, Clone, Serialize)]
pub struct OpReport {
    /// Index in the script.
    pub index: usize,
    /// Operation kind.
    pub kind: String,
    /// Human-readable outcome.
    pub summary: String,
    /// Wall time (ms).
    pub ms: f64,
}

/// One written object.
#[derive(Debug, Clone, Serialize)]
pub struct ObjectReport {
    /// Name.
    pub name: String,
    /// Points written.
    pub points: usize,
    /// Triangles of the meshed zero set.
    pub triangles: usize,
    /// Point file.
    pub ply: PathBuf,
    /// Mesh file.
    pub mesh: PathBuf,
}

/// The session's report.
#[derive(Debug, Clone, Serialize)]
pub struct SculptReport {
    /// Per operation.
    pub ops: Vec<OpReport>,
    /// Per object written.
    pub objects: Vec<ObjectReport>,
}

/// Run a script file.
pub fn run(args: &SculptArgs) -> anyhow::Result<SculptReport> {
    let text = std::fs::read_to_string(&args.script)
        .with_context(|| format!("reading {}", args.script.display()))?;
    let script = Script::parse(&text).with_context(|| format!("in {}", args.script.display()))?;
    let dir = args.script.parent().unwrap_or(Path::new(".")).to_path_buf();
    run_script(&script, &dir, &args.out)
}

/// Run a parsed script; relative paths resolve against `dir`.
pub fn run_script(script: &Script, dir: &Path, out: &Path) -> anyhow::Result<SculptReport> {
    let fit = FitParams::default();
    let mut scene = Scene::new();
    let mut names: Vec<String> = Vec::new();
    for spec in &script.object {
        let object =
            load_object(spec, dir, &fit).with_context(|| format!("object `{}`", spec.name))?;
        scene.add(object);
        names.push(spec.name.clone());
    }
    let id =
        |names: &[String], n: &str| names.iter().position(|x| x == n).context("unknown object");
    let dt = script.region.as_ref().map_or(1e-3, |r| r.dt);
    if let Some(r) = &script.region {
        let object = id(&names, &r.object)?;
        let mut params = region_params(r);
        if r.resample == Some(true) {
            params.resample = Some(resample_options(&scene.objects()[object].positions));
        }
        scene
            .open_region(object, DVec3::from(r.min), DVec3::from(r.max), params)
            .context("opening the region")?;
    }
    let mut ops = Vec::new();
    for (index, op) in script.op.iter().enumerate() {
        let t0 = Instant::now();
        let (kind, summary) = ops::run_op(&mut scene, &mut names, op, dt, dir, &fit)
            .with_context(|| format!("op[{index}]"))?;
        ops.push(OpReport {
            index,
            kind: kind.into(),
            summary,
            ms: t0.elapsed().as_secs_f64() * 1e3,
        });
    }
    if scene.region().is_some() {
        scene.close_region()?;
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut objects = Vec::new();
    for (o, name) in scene.objects().iter().zip(&names) {
        objects.push(write_object(o, name, out, script.mesh_resolution)?);
    }
    let report = SculptReport { ops, objects };
    std::fs::write(
        out.join("report.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    Ok(report)
}

/// Region resampling for an object of these points: its spacing estimated from at most
/// 20,000 of them.
pub(crate) fn resample_options(positions: &[DVec3]) -> ResampleOptions {
    ResampleOptions::new(sim_core::resample::spacing_sampled(positions, 20_000).max(1e-6))
}

pub(crate) fn region_params(r: &RegionSpec) -> RegionParams {
    let integrator = match r.integrator.as_str() {
        "forward_euler" => Integrator::forward_euler(r.accel_threshold),
        "backward_euler" => Integrator::backward_euler(),
        _ => Integrator::SymplecticEuler,
    };
    RegionParams {
        node: r.node.unwrap_or_default(),
        integrator,
        auto_upsample: r.auto_upsample,
        ..RegionParams::new(r.spacing, r.band)
    }
}

/// Reorient a file's `normals` when their signs are noise (some scanners write unoriented
/// normals; a field fitted to them breaks up), saying so: `sim_core::normals::orient_if_unoriented`.
pub(crate) fn orient_if_unoriented(
    what: &str,
    positions: &[glam::DVec3],
    normals: &mut [glam::DVec3],
) {
    if let Some(share) = sim_core::normals::orient_if_unoriented(positions, normals) {
        warn_reoriented(what, share);
    }
}

/// The warning for normals made consistent because their signs looked like noise (`share` of
/// side-by-side neighbours faced apart).
pub(crate) fn warn_reoriented(what: &str, share: f64) {
    tracing::warn!(
        "{what}: the normals' signs look unoriented ({:.0} % of neighbours side by side face \
         apart): made consistent, each part's top facing up",
        100.0 * share
    );
}

pub(crate) fn load_object(
    spec: &ObjectSpec,
    dir: &Path,
    fit: &FitParams,
) -> anyhow::Result<SceneObject> {
    let mut points = match (&spec.file, &spec.generate) {
        (Some(file), _) => {
            let path = dir.join(file);
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            let format =
                Format::from_extension(ext).with_context(|| format!("unknown format `{ext}`"))?;
            let f = std::fs::File::open(&path)
                .with_context(|| format!("opening {}", path.display()))?;
            let mut loaded = io::read(std::io::BufReader::new(f), format)?;
            loaded.normals_from_winding();
            let merged = loaded.points.merge_coincident();
            if merged > 0 {
                tracing::info!(
                    object = %spec.name,
                    merged,
                    "points repeated at one position merged (a mesh's split vertices)"
                );
            }
            if let Some(normals) = loaded.points.normals.as_mut() {
                orient_if_unoriented(&spec.name, &loaded.points.positions, normals);
            }
            if loaded.points.len() < FEW_POINTS {
                tracing::warn!(
                    object = %spec.name,
                    points = loaded.points.len(),
                    "too few points for a surface (under {FEW_POINTS}): the object shows \
                     and feels little or nothing"
                );
            }
            loaded.points
        }
        (None, Some(g)) if g.shape.starts_with("sample:") => {
            // A dense sampling of a mesh file (relative to the scene), scaled so its box's
            // longest side is `size`: a big-scan stand-in.
            let path = dir.join(&g.shape["sample:".len()..]);
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            let format =
                Format::from_extension(ext).with_context(|| format!("unknown format `{ext}`"))?;
            let f = std::fs::File::open(&path)
                .with_context(|| format!("opening {}", path.display()))?;
            let mesh = io::read(std::io::BufReader::new(f), format)?
                .mesh
                .with_context(|| format!("{} has no faces to sample", path.display()))?;
            crate::bigscan::sample_mesh(&mesh, g.points, g.seed, Some(g.size))
        }
        (None, Some(g)) => {
            let shape = match g.shape.as_str() {
                "sphere" => Shape::Sphere { radius: g.size },
                "torus" => Shape::Torus {
                    major: g.size,
                    minor: g.size2,
                },
                "plate" => Shape::Plate {
                    half_size: g.size,
                    thickness: g.size2,
                },
                _ => Shape::RoundedBox {
                    half: DVec3::splat(g.size),
                    radius: g.size2,
                },
            };
            shape.sample(g.points, g.seed)
        }
        (None, None) => anyhow::bail!("no `file` or `generate`"),
    };
    if let Some(size) = spec.size {
        let (centre, factor) = crate::bigscan::scaling_to(&points.positions, size);
        points
            .positions
            .iter_mut()
            .for_each(|p| *p = (*p - centre) * factor);
    }
    let offset = DVec3::from(spec.offset);
    points.positions.iter_mut().for_each(|p| *p += offset);
    if points.len() >= crate::bigscan::SPATIAL_ORDER_MIN {
        crate::bigscan::spatial_order(&mut points);
    }
    fit_object(spec.name.clone(), points, fit)
}

/// A file with fewer points than this (after merging repeats) is loaded with a warning: each
/// local fit takes its 20 nearest points, and a generated shape needs 50.
pub const FEW_POINTS: usize = 50;

/// Objects of at least this many points show a progress bar while they are fitted (on a
/// terminal): a million take about ten seconds.
pub const FIT_PROGRESS_MIN_POINTS: usize = 100_000;

pub(crate) fn fit_object(
    name: String,
    points: PointSet,
    fit: &FitParams,
) -> anyhow::Result<SceneObject> {
    let n = points.len();
    tracing::info!(object = %name, points = n, "fitting");
    if n < FIT_PROGRESS_MIN_POINTS {
        return Ok(SceneObject::fit(name, points, fit)?);
    }
    let bar = indicatif::ProgressBar::new(n as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "fitting `{name}` {{bar:40}} {{pos}}/{{len}} points ({{per_sec}})"
        ))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let object = SceneObject::fit_reporting(name, points, fit, &crate::fit::Bar(bar.clone()));
    bar.finish_and_clear();
    Ok(object?)
}

pub(crate) fn point_set(o: &SceneObject) -> PointSet {
    PointSet {
        positions: o.positions.clone(),
        normals: Some(o.normals.clone()),
        colors: Some(o.colors.clone()),
    }
}

fn write_object(
    o: &SceneObject,
    name: &str,
    out: &Path,
    resolution: usize,
) -> anyhow::Result<ObjectReport> {
    let ply = out.join(format!("{name}.ply"));
    let mesh_path = out.join(format!("{name}_mesh.ply"));
    let f = std::fs::File::create(&ply).with_context(|| format!("creating {}", ply.display()))?;
    io::write_points_ply(std::io::BufWriter::new(f), &point_set(o), false)?;
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &o.positions {
        (lo, hi) = (lo.min(*p), hi.max(*p));
    }
    let pad = (hi - lo).max_element() * 0.05 + 1e-6;
    let mut mesh = extract_zero_set(
        &o.field,
        (lo - DVec3::splat(pad), hi + DVec3::splat(pad)),
        resolution,
    );
    crate::fit::cut_unsupported_pieces(&mut mesh, &o.positions);
    let f = std::fs::File::create(&mesh_path)
        .with_context(|| format!("creating {}", mesh_path.display()))?;
    io::write_mesh_ply(std::io::BufWriter::new(f), &mesh)?;
    Ok(ObjectReport {
        name: name.into(),
        points: o.positions.len(),
        triangles: mesh.triangles.len(),
        ply,
        mesh: mesh_path,
    })
}

/// Print the report.
pub fn print(report: &SculptReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
        return Ok(());
    }
    for op in &report.ops {
        println!(
            "op[{}] {:<11} {:>9.1} ms  {}",
            op.index, op.kind, op.ms, op.summary
        );
    }
    for o in &report.objects {
        println!(
            "{}: {} points → {}, {} triangles → {}",
            o.name,
            o.points,
            o.ply.display(),
            o.triangles,
            o.mesh.display()
        );
    }
    Ok(())
}
