//! The interactive window (seed 000 Fig. 6): the live scene and a control panel.
//!
//! A native window (winit + wgpu through eframe, egui for the panel) shows the scene with the
//! `render` crate's lit surfel splats, the translucent probe, the haptic cursor, the contact
//! point, the sculpting region and the force arrow ([`crate::live::frames`] builds them, as for
//! the PNG frames). The scene is drawn into a texture on eframe's wgpu device and shown as an
//! image beside the panel, so one renderer serves the window, the PNG frames and `render`.
//!
//! The window is the rendering thread of a session ([`Link`]): it reads the newest
//! [`RenderSnapshot`](crate::live::shared::RenderSnapshot) and the force thread's last tick
//! (never waiting), and sends the panel's changes to the simulation thread as commands whose
//! answers it polls ([`panel::Pending`]).
//!
//! Input in the view: right-drag orbits, middle-drag (or Shift + right-drag) pans, Ctrl + wheel
//! zooms, F frames the scene. Without a device (`workstation view` without `--server`) the mouse
//! is the stylus ([`stylus`]): the cursor lives on the surface under the mouse (a ray cast into
//! the field the force thread reads, [`pick`]), the left button presses there, and each tool
//! does what a mouse user expects: touch and paint follow the surface under the mouse; the
//! point rope grabs the surface and a drag pulls it out by the distance dragged (Shift + drag
//! pushes it in); the curve rope rides the surface; the probe carves or pulls with its centre
//! at the wheel's depth below the surface. The wheel sets the selected tool's depth. Forces are
//! computed and plotted as with a device. With a device (`--server`) the mouse only moves the
//! camera (the wheel zooms). Keys: 1–6 select tools, Ctrl+S saves the scene, Ctrl+E exports
//! PLY/OBJ/STL, F12 saves a screenshot, Ctrl+Q quits.
//!
//! One job per file, arrows down only (the window imports `live`, never `crate::session`, whose
//! `demo` and `run` open it through [`open`] and a [`Link`]):
//! - here: `workstation view`'s arguments, the [`Link`] to a session, starting one, [`open`];
//! - `app`: the app's state, the per-frame update, status lines and the `--state` JSON;
//! - `actions`: what the panel's buttons and the keys do;
//! - `input`: the camera and the mouse as the device;
//! - [`stylus`], [`pick`]: what the mouse does with each tool, and the ray cast under it;
//! - `scene`: the scene's texture and the renderer drawing into it, screenshots to PNG;
//! - [`orbit`], [`panel`], [`plots`]: the camera's math, the control panel, the live plots.
//!
//! Inside the window: `app`, `actions` and `input` are one type's (the app's) methods split by
//! job; `app` → `scene`, [`orbit`], [`panel`], [`plots`]; `input` → [`stylus`] → [`pick`]; all
//! of them → `crate::live`.

mod actions;
mod app;
mod input;
pub mod orbit;
pub mod panel;
pub mod pick;
pub mod plots;
mod scene;
pub mod stylus;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, mpsc};

use anyhow::Context as _;
use eframe::egui;
use haptics_client::TransportKind;

use crate::live::mouse::MouseHand;
use crate::live::net::NetConfig;
use crate::live::scene_file::{DEMO_IMAGE, DEMO_SCENE, SceneFile, load_scene};
use crate::live::shared::Shared;
use crate::live::sim::SimCommand;
use crate::live::{CursorSource, Workstation};
use app::ViewApp;

/// Arguments of `workstation view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// Scene file, or a point or mesh file to sculpt (.ply .obj .off .stl .xyz .pwn): it opens
    /// scaled to 10 cm across and centred, as the demo ball is, with the demo's tools and
    /// material, the region around all of it; saves are in those scene metres [default: the
    /// demo's scene, examples/live/demo.toml, without its scripted phases].
    #[arg(value_name = "SCENE.toml|MODEL")]
    pub scene: Option<PathBuf>,
    /// Connect to this haptics server and feel the scene with its device. Without it the mouse
    /// is the stylus (no device, no server): the cursor rides the surface under the mouse, the
    /// left button presses there; touch and paint follow the surface, a rope press grabs it and
    /// a drag pulls it out by the distance dragged (Shift + drag: in), the probe carves or pulls
    /// with its centre at the wheel's depth below the surface (the wheel sets the tool's depth;
    /// Ctrl + wheel zooms).
    #[arg(long, value_name = "ADDR")]
    pub server: Option<SocketAddr>,
    /// The server's certificate (PEM) to pin; required with --server.
    #[arg(long, value_name = "FILE", requires = "server")]
    pub cert: Option<PathBuf>,
    /// Transport to the server.
    #[arg(long, value_enum, default_value_t = TransportKind::Udp)]
    pub transport: TransportKind,
    /// Where saved scenes, exports and screenshots go.
    #[arg(long, default_value = "out/view")]
    pub out: PathBuf,
    /// Save the window's own pixels to this PNG after --frames frames, then exit.
    #[arg(long, value_name = "OUT.png")]
    pub screenshot: Option<PathBuf>,
    /// Frames to show before the screenshot (or before exiting, without --screenshot).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub frames: Option<u64>,
    /// Write the window's state (frames, frame rate, selected tool, where the tool buttons are)
    /// as JSON to this file twice a second and at exit: for scripts and tests.
    #[arg(long, value_name = "FILE.json")]
    pub state: Option<PathBuf>,
    /// Window size in logical pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x800", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Joining a shared scene: mouse strokes are shared, other stations' cursors drawn.
    #[command(flatten)]
    pub share: crate::share::station::ShareArgs,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("`{s}`: expected WIDTHxHEIGHT, e.g. 1280x800"))?;
    let side = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (200..=8192).contains(n))
            .ok_or_else(|| format!("`{v}`: each side must be 200..=8192 pixels"))
    };
    Ok((side(w)?, side(h)?))
}

/// Whether a window can open here: an X11 display (or Wayland, when built with the `wayland`
/// feature).
pub fn display_available() -> bool {
    std::env::var_os("DISPLAY").is_some_and(|d| !d.is_empty())
        || (cfg!(feature = "wayland")
            && std::env::var_os("WAYLAND_DISPLAY").is_some_and(|d| !d.is_empty()))
}

/// Whether the window can draw: it needs a Vulkan adapter, a GPU or Mesa's software driver
/// (lavapipe). The error says which package to install.
pub fn window_gpu() -> anyhow::Result<()> {
    render::Renderer::headless(1, 1).map(drop).map_err(|e| {
        anyhow::anyhow!(
            "the window needs a GPU driver or Mesa's software Vulkan driver: {e}. Without a \
             window, `workstation demo --no-window`, `run --frames` and `render` draw on the CPU"
        )
    })
}

/// What the window needs of a running session.
#[derive(Debug, Clone)]
pub struct Link {
    /// The session's shared state.
    pub shared: Arc<Shared>,
    /// Commands to its simulation thread.
    pub commands: mpsc::Sender<SimCommand>,
    /// The mouse, when it is the device.
    pub mouse: Option<Arc<MouseHand>>,
    /// The scene (initial settings, view direction).
    pub scene: SceneFile,
    /// Where the scene's relative files are.
    pub dir: PathBuf,
    /// Says where the cursor comes from, for the status line.
    pub source: String,
    /// Lines from whoever drives the session (the demo's phases), shown in the panel.
    pub log: Arc<Mutex<Vec<String>>>,
    /// The shared scene joined (`--share`): other stations' cursors are drawn from it.
    pub remote: Option<Arc<crate::share::station::ShareStats>>,
    /// The share thread, when the window's session owns it (stopped with the window).
    pub station: Option<Arc<crate::share::station::Station>>,
}

impl Link {
    /// The link to a workstation.
    pub fn to(ws: &Workstation, scene: &SceneFile, dir: PathBuf, source: &CursorSource) -> Self {
        let (mouse, label) = match source {
            CursorSource::Mouse(h) => (Some(Arc::clone(h)), "mouse (no device)".to_owned()),
            CursorSource::Server(cfg) => (
                None,
                format!("server {} over {:?}", cfg.server, cfg.transport),
            ),
        };
        Self {
            shared: Arc::clone(&ws.shared),
            commands: ws.commander(),
            mouse,
            scene: scene.clone(),
            dir,
            source: label,
            log: Arc::default(),
            remote: None,
            station: None,
        }
    }
}

/// How the window's session was started, to start another on a new scene (Load).
#[derive(Debug, Clone)]
pub struct Starter {
    /// The server, or `None` for the mouse.
    pub server: Option<NetConfig>,
    /// The scene shown (`None`: the demo's).
    pub scene: Option<PathBuf>,
    /// Joining a shared scene (`--share`).
    pub share: crate::share::station::ShareArgs,
}

impl Starter {
    /// Start a session on the scene at `scene_path` (default: the demo's scene).
    pub fn start(
        &self,
        scene_path: Option<&Path>,
        out: &Path,
    ) -> anyhow::Result<(Workstation, Link)> {
        let (scene, dir) = load_view_scene(scene_path, out)?;
        let source = match &self.server {
            Some(cfg) => CursorSource::Server(cfg.clone()),
            None => CursorSource::Mouse(Arc::default()),
        };
        let ws = Workstation::start(&scene, dir.clone(), source.clone(), None)?;
        let mut link = Link::to(&ws, &scene, dir, &source);
        let name = scene_path.map_or_else(|| PathBuf::from("demo.toml"), Path::to_path_buf);
        if let Some(cfg) = self.share.resolve(&name, false)? {
            let station = Arc::new(crate::share::station::Station::start(
                cfg,
                ws.commander(),
                Arc::clone(&ws.shared),
            )?);
            link.remote = Some(Arc::clone(&station.stats));
            link.station = Some(station);
        }
        Ok((ws, link))
    }
}

/// The scene at `path`, or the demo's scene without its phases (its image written to `out`).
fn load_view_scene(path: Option<&Path>, out: &Path) -> anyhow::Result<(SceneFile, PathBuf)> {
    match path {
        Some(p) => {
            let scene = load_scene(p)?;
            let dir = p
                .parent()
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
            Ok((scene, dir))
        }
        None => {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            std::fs::write(out.join("ring.png"), DEMO_IMAGE)?;
            let mut scene =
                SceneFile::parse(DEMO_SCENE).map_err(|e| anyhow::anyhow!("the demo scene: {e}"))?;
            scene.phase.clear();
            Ok((scene, out.to_path_buf()))
        }
    }
}

/// When to take the screenshot and whether to exit.
#[derive(Debug, Clone, Default)]
pub struct Exit {
    /// Save the window's pixels here …
    pub screenshot: Option<PathBuf>,
    /// … after this many frames, then exit.
    pub frames: Option<u64>,
    /// Write the state JSON here.
    pub state: Option<PathBuf>,
}

/// `workstation view`: open the window on a scene; returns when it is closed.
pub fn run(args: &ViewArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        display_available(),
        "no display: `workstation view` opens a window (set DISPLAY, or run it under `xvfb-run`); \
         for pictures without a window use `workstation render` or `workstation run --frames`"
    );
    window_gpu()?;
    let server = NetConfig::from_flags(args.server, args.cert.as_deref(), args.transport)?;
    let starter = Starter {
        server,
        scene: args.scene.clone(),
        share: args.share.clone(),
    };
    let (ws, link) = starter.start(args.scene.as_deref(), &args.out)?;
    let exit = Exit {
        screenshot: args.screenshot.clone(),
        frames: args.frames,
        state: args.state.clone(),
    };
    open(
        link,
        Some((ws, starter)),
        args.out.clone(),
        exit,
        args.size,
        "workstation view",
    )
}

/// Open the window on a session and block until it is closed. `owned`: the workstation the
/// window owns (stopped when it closes) and how to start another (Load); `None` when someone
/// else drives the session (the demo).
pub fn open(
    link: Link,
    owned: Option<(Workstation, Starter)>,
    out: PathBuf,
    exit: Exit,
    size: (u32, u32),
    title: &str,
) -> anyhow::Result<()> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([size.0 as f32, size.1 as f32])
            .with_title(title),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let failed: Arc<Mutex<Option<String>>> = Arc::default();
    let f = Arc::clone(&failed);
    eframe::run_native(
        title,
        options,
        Box::new(move |cc| {
            let app = ViewApp::new(cc, link, owned, out, exit, f).map_err(
                |e| -> Box<dyn std::error::Error + Send + Sync> { format!("{e:#}").into() },
            )?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the window failed: {e}"))?;
    match failed.lock().map(|mut f| f.take()) {
        Ok(Some(e)) => anyhow::bail!("{e}"),
        _ => Ok(()),
    }
}
