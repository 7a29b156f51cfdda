//! `workstation render`: a point or mesh file (PLY, OFF, OBJ, STL, XYZ) rendered headless to a PNG
//! with the live workstation's renderer, to look at what a session saved without a GUI.

use std::path::PathBuf;

use anyhow::Context as _;
use sim_core::io::{self, Format};

use super::frames::FrameMaker;
use super::points::ChunkedPoints;
use super::scene_file::RenderSpec;
use super::shared::{RenderSnapshot, Shared};

/// Arguments of `workstation render`.
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// The file: its vertices are drawn as splats (a mesh's vertices with their normals, or
    /// with normals from its faces when it has none).
    pub file: PathBuf,
    /// The PNG to write.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Image width and height (px).
    #[arg(long, num_args = 2, default_values_t = [1280, 720])]
    pub size: Vec<u32>,
    /// Who draws: `auto` (a GPU; the CPU splatter where Vulkan is software or missing),
    /// `gpu` (fail without one) or `software`. The HAPTIC_RENDER environment variable sets
    /// the same for `demo`, `run --frames` and here.
    #[arg(long, default_value = "auto", value_parser = parse_backend)]
    pub renderer: render::BackendChoice,
    /// Direction the camera looks along.
    #[arg(long, num_args = 3, default_values_t = [-0.35, -0.45, -1.0], allow_negative_numbers = true)]
    pub view_dir: Vec<f64>,
}

fn parse_backend(s: &str) -> Result<render::BackendChoice, String> {
    s.parse().map_err(|e: render::RenderError| e.to_string())
}

/// Render `args.file` to `args.out`.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let ext = args.file.extension().and_then(|e| e.to_str()).unwrap_or("");
    let format = Format::from_extension(ext).with_context(|| format!("unknown format `{ext}`"))?;
    let f = std::fs::File::open(&args.file)
        .with_context(|| format!("opening {}", args.file.display()))?;
    let loaded = io::read(std::io::BufReader::new(f), format)?;
    let p = loaded.points;
    let n = p.positions.len();
    let normals = match (p.normals, &loaded.mesh) {
        (Some(nm), _) => nm,
        (None, Some(m)) if m.normals.len() == n => m.normals.clone(),
        // A mesh without normals: its faces' area-weighted normals.
        (None, Some(m)) if m.vertices.len() == n && !m.triangles.is_empty() => m.vertex_normals(),
        _ => anyhow::bail!(
            "{} has no normals to orient the splats (and no faces to compute them from)",
            args.file.display()
        ),
    };
    let mut normals = normals;
    crate::sculpt::orient_if_unoriented(
        &args.file.display().to_string(),
        &p.positions,
        &mut normals,
    );
    let colors = p.colors.unwrap_or_else(|| vec![[200, 200, 200]; n]);
    let snap = RenderSnapshot {
        points: ChunkedPoints::from_slices(&p.positions, &normals, &colors),
        ..Default::default()
    };
    let spec = RenderSpec {
        width: args.size[0],
        height: args.size[1],
        view_dir: [args.view_dir[0], args.view_dir[1], args.view_dir[2]],
        interval_s: 1.0,
    };
    let mut maker = FrameMaker::with_backend(&spec, args.renderer)?;
    maker
        .render(&snap, &Shared::default())?
        .save_png(&args.out)?;
    println!("wrote {} ({n} splats)", args.out.display());
    Ok(())
}
