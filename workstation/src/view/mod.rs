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
//! is the device: it moves the cursor in the plane facing the camera, the wheel moves that
//! plane nearer or farther, and the left button is the stylus button. Keys: 1–6 select tools,
//! Ctrl+S saves the scene, Ctrl+E exports PLY/OBJ/STL, F12 saves a screenshot, Ctrl+Q quits.

pub mod orbit;
pub mod panel;
pub mod plots;

use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use eframe::egui::{self, PointerButton, Sense};
use eframe::egui_wgpu;
use glam::DVec3;
use haptics_client::TransportKind;

use crate::live::frames::{self, SplatCache};
use crate::live::mouse::MouseHand;
use crate::live::net::NetConfig;
use crate::live::scene_file::{SceneFile, ToolKind};
use crate::live::shared::Shared;
use crate::live::sim::{Settings, SimCommand};
use crate::live::{CursorSource, Workstation};
use orbit::Orbit;
use panel::{Action, Panel, Pending};
use plots::{History, Sample};

/// Arguments of `workstation view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// Scene file [default: the demo's scene, examples/live/demo.toml, without its scripted
    /// phases].
    #[arg(value_name = "SCENE.toml")]
    pub scene: Option<PathBuf>,
    /// Connect to this haptics server and feel the scene with its device. Without it the mouse
    /// drives the cursor (no device, no server).
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
        let link = Link::to(&ws, &scene, dir, &source);
        Ok((ws, link))
    }
}

/// The scene at `path`, or the demo's scene without its phases (its image written to `out`).
fn load_view_scene(path: Option<&Path>, out: &Path) -> anyhow::Result<(SceneFile, PathBuf)> {
    match path {
        Some(p) => {
            let scene = crate::live::run::load_scene(p)?;
            let dir = p
                .parent()
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
            Ok((scene, dir))
        }
        None => {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            std::fs::write(out.join("ring.png"), crate::live::demo::DEMO_IMAGE)?;
            let mut scene = SceneFile::parse(crate::live::demo::DEMO_SCENE)
                .map_err(|e| anyhow::anyhow!("the demo scene: {e}"))?;
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
    let server = NetConfig::from_flags(args.server, args.cert.as_deref(), args.transport)?;
    let starter = Starter {
        server,
        scene: args.scene.clone(),
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

/// The scene's texture on eframe's device, and the renderer that draws into it.
struct Gpu {
    renderer: render::Renderer,
    egui: Arc<egui::mutex::RwLock<egui_wgpu::Renderer>>,
    color: Option<(wgpu::TextureView, wgpu::TextureView, (u32, u32))>,
    texture: Option<egui::TextureId>,
}

impl Gpu {
    fn new(state: &egui_wgpu::RenderState) -> Self {
        let renderer = render::Renderer::with_device(
            state.device.clone(),
            state.queue.clone(),
            state.adapter.get_info(),
            render::Renderer::HEADLESS_FORMAT,
        );
        Self {
            renderer,
            egui: Arc::clone(&state.renderer),
            color: None,
            texture: None,
        }
    }

    /// The texture for a view of `size` pixels (recreated when the size changes).
    fn target(&mut self, size: (u32, u32)) -> egui::TextureId {
        if self.color.as_ref().is_none_or(|c| c.2 != size) {
            let device = self.renderer.device();
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("window scene"),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: render::Renderer::HEADLESS_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
            });
            // The renderer writes sRGB-encoded bytes through the sRGB view; egui blends in
            // gamma space, so it samples the same bytes through a plain view (no decoding).
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let shown = texture.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8Unorm),
                ..Default::default()
            });
            let depth = self.renderer.create_depth_view(size.0, size.1);
            let mut egui = self.egui.write();
            match self.texture {
                Some(id) => egui.update_egui_texture_from_wgpu_texture(
                    device,
                    &shown,
                    wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    self.texture = Some(egui.register_native_texture(
                        device,
                        &shown,
                        wgpu::FilterMode::Linear,
                    ));
                }
            }
            self.color = Some((view, depth, size));
        }
        self.texture.expect("registered above")
    }

    fn draw(
        &mut self,
        size: (u32, u32),
        splats: &[render::Splat],
        overlay: &render::Overlay,
        camera: &render::Camera,
    ) -> anyhow::Result<egui::TextureId> {
        let id = self.target(size);
        let (color, depth, _) = self.color.as_ref().expect("made by target");
        let mut encoder =
            self.renderer
                .device()
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("window scene"),
                });
        self.renderer
            .draw(&mut encoder, color, depth, size, splats, overlay, camera)?;
        self.renderer.queue().submit(Some(encoder.finish()));
        Ok(id)
    }
}

/// The window's state in `--state` JSON.
#[derive(Debug, serde::Serialize)]
struct StateFile<'a> {
    frames: u64,
    fps: f64,
    /// The tool the simulation has selected (from its newest snapshot).
    tool: Option<&'static str>,
    connected: bool,
    points: usize,
    /// Where the tool buttons are, in window pixels: `[x, y, width, height]`.
    tool_buttons: BTreeMap<&'static str, [f32; 4]>,
    /// Where the scene view is, in window pixels.
    view: [f32; 4],
    messages: &'a VecDeque<String>,
}

struct ViewApp {
    link: Link,
    owned: Option<(Workstation, Starter)>,
    gpu: Gpu,
    splats: SplatCache,
    orbit: Option<Orbit>,
    /// The mouse cursor's plane: metres from the eye.
    depth: f64,
    panel: Panel,
    pending: Vec<Pending>,
    messages: VecDeque<String>,
    history: History,
    started: Instant,
    last_frame: Instant,
    frames: u64,
    fps: f64,
    exit: Exit,
    shots: (
        mpsc::Sender<Arc<egui::ColorImage>>,
        mpsc::Receiver<Arc<egui::ColorImage>>,
    ),
    shot_path: Option<PathBuf>,
    closing: bool,
    last_state: Instant,
    tool_rects: BTreeMap<&'static str, egui::Rect>,
    view_rect: egui::Rect,
    failed: Arc<Mutex<Option<String>>>,
    stopped_said: bool,
}

impl ViewApp {
    fn new(
        cc: &eframe::CreationContext<'_>,
        link: Link,
        owned: Option<(Workstation, Starter)>,
        out: PathBuf,
        exit: Exit,
        failed: Arc<Mutex<Option<String>>>,
    ) -> anyhow::Result<Self> {
        let state = cc
            .wgpu_render_state
            .as_ref()
            .context("eframe started without wgpu")?;
        tracing::info!(adapter = ?state.adapter.get_info().name, "window opened");
        let panel = Self::panel_for(&link, &out, owned.is_some());
        let now = Instant::now();
        Ok(Self {
            gpu: Gpu::new(state),
            splats: SplatCache::default(),
            orbit: None,
            depth: 0.0,
            panel,
            pending: Vec::new(),
            messages: VecDeque::new(),
            history: History::new(10.0),
            started: now,
            last_frame: now,
            frames: 0,
            fps: 0.0,
            exit,
            shots: mpsc::channel(),
            shot_path: None,
            closing: false,
            last_state: now,
            tool_rects: BTreeMap::new(),
            view_rect: egui::Rect::NOTHING,
            failed,
            stopped_said: false,
            link,
            owned,
        })
    }

    fn panel_for(link: &Link, out: &Path, can_load: bool) -> Panel {
        let image = link.dir.join("ring.png");
        let image = if image.exists() {
            image.display().to_string()
        } else {
            String::new()
        };
        let mut p = Panel::new(
            Settings::of(&link.scene),
            link.scene.tools.selected,
            out.to_path_buf(),
            image,
        );
        p.can_load = can_load;
        p
    }

    fn say(&mut self, line: impl Into<String>) {
        let line = line.into();
        tracing::info!("{line}");
        self.messages.push_back(line);
        while self.messages.len() > 8 {
            self.messages.pop_front();
        }
    }

    fn send(&mut self, cmd: SimCommand) {
        if self.link.commands.send(cmd).is_err() {
            self.say("the simulation has stopped");
        }
    }

    fn out_dir(&self) -> PathBuf {
        PathBuf::from(&self.panel.out_dir)
    }

    fn act(&mut self, ctx: &egui::Context, action: Action) {
        match action {
            Action::Select(t) => {
                self.panel.tool = t;
                self.send(SimCommand::Select(t));
            }
            Action::ApplyTools | Action::ApplyMaterial => {
                let (tx, rx) = mpsc::channel();
                let what = if action == Action::ApplyTools {
                    "tool settings"
                } else {
                    "material and integrator"
                };
                self.send(SimCommand::Configure(
                    Box::new(self.panel.settings.clone()),
                    tx,
                ));
                // Tool settings are sent while a slider moves: only errors are worth a line.
                let quiet = action == Action::ApplyTools;
                self.pending.push(Pending::new(what, rx, move |()| {
                    if quiet {
                        String::new()
                    } else {
                        format!("{what} applied")
                    }
                }));
            }
            Action::Csg { op, shape, size } => {
                let at = self.link.shared.haptic.cursor();
                let (tx, rx) = mpsc::channel();
                self.send(SimCommand::CsgPrimitive {
                    op,
                    shape: shape.into(),
                    size,
                    at,
                    reply: tx,
                });
                self.pending
                    .push(Pending::new("CSG", rx, |(kind, s)| format!("{kind}: {s}")));
            }
            Action::Emboss { image, depth, size } => {
                let Some(contact) = self.link.shared.haptic.contact() else {
                    return self.say("emboss: touch the surface first");
                };
                let snap = self.link.shared.render.load_full();
                let Some(object) = snap.as_ref().and_then(|s| s.region_object.clone()) else {
                    return self.say("emboss: no sculpted object");
                };
                let normal = (self.link.shared.haptic.cursor() - contact)
                    .try_normalize()
                    .or_else(|| self.orbit.map(|o| o.back()))
                    .unwrap_or(DVec3::Z);
                let u = normal.any_orthonormal_vector();
                let v = normal.cross(u);
                let origin = contact - 0.5 * size * (u + v);
                let op = crate::sculpt::script::Op::Emboss {
                    object,
                    image: image.display().to_string(),
                    mapping: sim_core::tools::emboss::Mapping::Planar {
                        origin,
                        u_axis: u * size,
                        v_axis: v * size,
                    },
                    depth,
                };
                let (tx, rx) = mpsc::channel();
                self.send(SimCommand::Op(Box::new(op), tx));
                self.pending.push(Pending::new("emboss", rx, |(kind, s)| {
                    format!("{kind}: {s}")
                }));
            }
            Action::SaveScene => {
                let dir = self.out_dir().join(format!("scene_{}", stamp()));
                let (tx, rx) = mpsc::channel();
                self.send(SimCommand::SaveScene(dir, tx));
                self.pending.push(Pending::new("save scene", rx, |p| {
                    format!(
                        "saved {} (open it with `workstation view {}`)",
                        p.display(),
                        p.display()
                    )
                }));
            }
            Action::Export => {
                let dir = self.out_dir().join(format!("export_{}", stamp()));
                let (tx, rx) = mpsc::channel();
                self.send(SimCommand::Save(dir.clone(), tx));
                self.pending.push(Pending::new("export", rx, move |s| {
                    format!(
                        "exported {} points and {} triangles to {}",
                        s.points,
                        s.triangles,
                        dir.display()
                    )
                }));
            }
            Action::Screenshot => {
                let path = self.out_dir().join(format!("screenshot_{}.png", stamp()));
                self.request_screenshot(ctx, path);
            }
            Action::Load(path) => self.load(&path),
            Action::Frame => {
                self.orbit = None;
                self.depth = 0.0;
            }
        }
    }

    fn load(&mut self, path: &Path) {
        let Some((_, starter)) = &self.owned else {
            return self.say("loading is not possible while the demo drives the session");
        };
        let mut starter = starter.clone();
        // The old session ends first: a server holds one session at a time.
        if let Some((ws, _)) = self.owned.take() {
            drop(ws);
        }
        let out = self.out_dir();
        match starter.start(Some(path), &out) {
            Ok((ws, link)) => {
                self.panel = Self::panel_for(&link, &out, true);
                self.link = link;
                starter.scene = Some(path.to_path_buf());
                self.owned = Some((ws, starter));
                self.orbit = None;
                self.depth = 0.0;
                self.say(format!("loaded {}", path.display()));
            }
            Err(e) => {
                self.say(format!("loading {}: {e:#}", path.display()));
                // Back to the scene shown before (as it was when last saved or loaded).
                match starter.start(starter.scene.as_deref(), &out) {
                    Ok((ws, link)) => {
                        self.link = link;
                        self.owned = Some((ws, starter));
                    }
                    Err(e) => self.say(format!("restarting: {e:#}")),
                }
            }
        }
    }

    fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
        if self.shot_path.is_some() {
            return;
        }
        let tx = self.shots.0.clone();
        ctx.request_screenshot(move |image| {
            let _ = tx.send(image);
        });
        self.shot_path = Some(path);
    }

    fn poll(&mut self, ctx: &egui::Context) {
        let mut lines = Vec::new();
        self.pending.retain_mut(|p| match p.poll() {
            None => true,
            Some(Ok(line)) => {
                if !line.is_empty() {
                    lines.push(line);
                }
                false
            }
            Some(Err(e)) => {
                lines.push(format!("{}: {e}", p.what()));
                false
            }
        });
        if let Ok(mut log) = self.link.log.lock() {
            lines.append(&mut log);
        }
        for l in lines {
            self.say(l);
        }
        if let Ok(image) = self.shots.1.try_recv()
            && let Some(path) = self.shot_path.take()
        {
            match save_color_image(&image, &path) {
                Ok(()) => self.say(format!("screenshot {}", path.display())),
                Err(e) => {
                    let e = format!("screenshot {}: {e:#}", path.display());
                    if self.exit.screenshot.is_some()
                        && let Ok(mut f) = self.failed.lock()
                    {
                        *f = Some(e.clone());
                    }
                    self.say(e);
                }
            }
            if self.exit.screenshot.is_some() {
                self.close(ctx);
            }
        }
        if self.link.shared.stopping() && !self.stopped_said {
            self.stopped_said = true;
            self.say("the session has ended: the view shows its last state");
        }
    }

    fn close(&mut self, ctx: &egui::Context) {
        self.closing = true;
        self.write_state();
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    fn keys(&mut self, ctx: &egui::Context) -> Vec<Action> {
        if ctx.egui_wants_keyboard_input() {
            return Vec::new();
        }
        let mut actions = Vec::new();
        ctx.input(|i| {
            for (k, key) in [
                egui::Key::Num1,
                egui::Key::Num2,
                egui::Key::Num3,
                egui::Key::Num4,
                egui::Key::Num5,
                egui::Key::Num6,
            ]
            .into_iter()
            .enumerate()
            {
                if i.key_pressed(key) && !i.modifiers.ctrl {
                    actions.push(Action::Select(panel::TOOLS[k].0));
                }
            }
            if i.key_pressed(egui::Key::F) && !i.modifiers.ctrl {
                actions.push(Action::Frame);
            }
            if i.modifiers.ctrl && i.key_pressed(egui::Key::S) {
                actions.push(Action::SaveScene);
            }
            if i.modifiers.ctrl && i.key_pressed(egui::Key::E) {
                actions.push(Action::Export);
            }
            if i.key_pressed(egui::Key::F12) {
                actions.push(Action::Screenshot);
            }
        });
        if ctx.input(|i| i.modifiers.ctrl && i.key_pressed(egui::Key::Q)) {
            self.close(ctx);
        }
        actions
    }

    fn sample(&mut self) {
        let s = &self.link.shared;
        let n = &s.net;
        self.history.push(Sample {
            t: self.started.elapsed().as_secs_f64(),
            force_hz: s.force_loop.rate_hz(),
            servo_hz: n.servo_hz.get(),
            rtt_us: n.force_rtt_us.get().p50,
            force_n: s.haptic.force().length(),
            step_us: s.sim_loop.work_us.get().p50,
            sim_hz: s.sim_loop.rate_hz(),
        });
    }

    fn write_state(&mut self) {
        let Some(path) = &self.exit.state else { return };
        self.last_state = Instant::now();
        let px = |r: &egui::Rect| [r.min.x, r.min.y, r.width(), r.height()];
        let snap = self.link.shared.render.load_full();
        let state = StateFile {
            frames: self.frames,
            fps: self.fps,
            tool: snap.as_ref().and_then(|s| s.tool).map(ToolKind::name),
            connected: self.link.shared.net.connected.load(Ordering::Relaxed),
            points: snap.as_ref().map_or(0, |s| s.positions.len()),
            tool_buttons: self.tool_rects.iter().map(|(k, r)| (*k, px(r))).collect(),
            view: px(&self.view_rect),
            messages: &self.messages,
        };
        let tmp = path.with_extension("json.tmp");
        let written = serde_json::to_vec_pretty(&state)
            .map_err(anyhow::Error::from)
            .and_then(|b| Ok(std::fs::write(&tmp, b)?))
            .and_then(|()| Ok(std::fs::rename(&tmp, path)?));
        if let Err(e) = written {
            tracing::warn!("writing {}: {e:#}", path.display());
        }
    }

    fn status(&self, ui: &mut egui::Ui) {
        let s = &self.link.shared;
        let connected = s.net.connected.load(Ordering::Relaxed);
        ui.label(format!("cursor: {}", self.link.source));
        ui.label(if s.stopping() {
            "session ended".to_owned()
        } else if connected {
            format!(
                "connected · sessions {} · cursors {}",
                s.net.sessions.load(Ordering::Relaxed),
                s.net.cursors.load(Ordering::Relaxed)
            )
        } else {
            "waiting for the server …".to_owned()
        });
        let points = s.render.load().as_ref().map_or(0, |r| r.positions.len());
        ui.label(format!(
            "{points} points · {:.0} frames/s · force loop {:.0} Hz · simulation {:.0} Hz",
            self.fps,
            s.force_loop.rate_hz(),
            s.sim_loop.rate_hz()
        ));
    }

    /// The scene view: draw, then handle the mouse.
    fn view(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        self.view_rect = rect;
        let ppp = ui.ctx().pixels_per_point();
        let size = (
            ((rect.width() * ppp).round() as u32).max(1),
            ((rect.height() * ppp).round() as u32).max(1),
        );
        let Some(snap) = self.link.shared.render.load_full() else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "loading the scene …",
                egui::FontId::proportional(18.0),
                egui::Color32::LIGHT_GRAY,
            );
            return;
        };
        let orbit = self.orbit.get_or_insert_with(|| {
            let (lo, hi) = frames::scene_bounds(&snap);
            Orbit::framing(lo, hi, DVec3::from(self.link.scene.render.view_dir))
        });
        if self.depth <= 0.0 || !self.depth.is_finite() {
            // The cursor's plane starts just in front of the nearest point: the wheel then
            // pushes it into the surface.
            let (eye, f) = (orbit.eye(), orbit.forward());
            let nearest = snap
                .positions
                .iter()
                .map(|p| (*p - eye).dot(f))
                .fold(f64::INFINITY, f64::min);
            self.depth = if nearest.is_finite() && nearest > 0.0 {
                nearest - 0.02 * orbit.scene_radius
            } else {
                orbit.distance
            };
        }

        // Camera.
        let (w, h) = (rect.width() as f64, rect.height() as f64);
        let shift = ui.input(|i| i.modifiers.shift);
        if response.dragged_by(PointerButton::Middle)
            || (shift && response.dragged_by(PointerButton::Secondary))
        {
            let d = response.drag_delta();
            orbit.pan(d.x as f64, d.y as f64, h);
        } else if response.dragged_by(PointerButton::Secondary) {
            let d = response.drag_delta();
            orbit.orbit(d.x as f64 * 0.01, d.y as f64 * 0.01);
        }
        let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta.y as f64, i.zoom_delta() as f64));
        if response.hovered() {
            if zoom != 1.0 {
                orbit.zoom(1.0 / zoom);
            }
            if scroll != 0.0 {
                if self.link.mouse.is_some() {
                    // Wheel up pushes the cursor's plane away from the eye.
                    self.depth = (self.depth - scroll * 2e-4 * orbit.distance).clamp(
                        0.05 * orbit.distance,
                        orbit.distance + 3.0 * orbit.scene_radius,
                    );
                } else {
                    orbit.zoom((-scroll * 0.002).exp());
                }
            }
        }
        // The mouse as the device.
        if let Some(hand) = &self.link.mouse {
            let pressed = response.is_pointer_button_down_on()
                && ui.input(|i| i.pointer.button_down(PointerButton::Primary));
            if let Some(p) = response.hover_pos().or(response.interact_pointer_pos()) {
                let q = p - rect.min;
                let at = orbit.point_at_depth(q.x as f64, q.y as f64, w, h, self.depth);
                hand.set(at, u16::from(pressed));
            } else {
                let (at, _) = hand.get();
                hand.set(at, 0);
            }
        }

        // Draw.
        let camera = orbit.camera();
        let overlay = frames::overlay(&snap, &self.link.shared);
        let splats = self.splats.splats(&snap);
        match self.gpu.draw(size, splats, &overlay, &camera) {
            Ok(id) => {
                let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
                ui.painter().image(id, rect, uv, egui::Color32::WHITE);
            }
            Err(e) => {
                ui.painter().text(
                    rect.center(),
                    egui::Align2::CENTER_CENTER,
                    format!("rendering failed: {e:#}"),
                    egui::FontId::proportional(16.0),
                    egui::Color32::RED,
                );
            }
        }
        let hint = if self.link.mouse.is_some() {
            "mouse = stylus: move · left button presses · wheel: nearer/farther\nright-drag orbit · middle-drag pan · Ctrl+wheel zoom · F frame"
        } else {
            "right-drag orbit · middle-drag pan · wheel zoom · F frame"
        };
        ui.painter().text(
            rect.left_bottom() + egui::vec2(8.0, -8.0),
            egui::Align2::LEFT_BOTTOM,
            hint,
            egui::FontId::proportional(13.0),
            egui::Color32::from_gray(170),
        );
    }
}

impl eframe::App for ViewApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let now = Instant::now();
        let dt = now.duration_since(self.last_frame).as_secs_f64();
        self.last_frame = now;
        if dt > 0.0 && self.frames > 0 {
            self.fps += (1.0 / dt - self.fps) * if self.fps == 0.0 { 1.0 } else { 0.1 };
        }
        self.frames += 1;
        self.poll(&ctx);
        self.sample();
        let mut actions = self.keys(&ctx);

        let contact = self.link.shared.haptic.contact();
        let mut rects = BTreeMap::new();
        egui::Panel::left("panel")
            .resizable(true)
            .default_size(330.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    ui.heading("Haptic sculpting");
                    self.status(ui);
                    ui.separator();
                    actions.extend(self.panel.tools(ui, |tool, r| {
                        rects.insert(tool.name(), r);
                    }));
                    actions.extend(self.panel.settings(ui, contact));
                    egui::CollapsingHeader::new("Live plots")
                        .default_open(true)
                        .show(ui, |ui| self.history.show(ui));
                    ui.separator();
                    for m in &self.messages {
                        ui.small(m.as_str());
                    }
                });
            });
        let ppp = ctx.pixels_per_point();
        self.tool_rects = rects.into_iter().map(|(k, r)| (k, r * ppp)).collect();
        egui::CentralPanel::no_frame().show(ui, |ui| self.view(ui));
        self.view_rect = self.view_rect * ppp;
        for a in actions {
            self.act(&ctx, a);
        }

        if let Some(n) = self.exit.frames
            && self.frames >= n
            && !self.closing
        {
            match self.exit.screenshot.clone() {
                Some(path) => {
                    if self.shot_path.is_none() {
                        self.request_screenshot(&ctx, path);
                    }
                }
                None => self.close(&ctx),
            }
        }
        if self.exit.state.is_some()
            && now.duration_since(self.last_state) > Duration::from_millis(500)
        {
            self.write_state();
        }
        ctx.request_repaint();
    }

    fn on_exit(&mut self) {
        self.write_state();
    }
}

/// A timestamp for file names: seconds since the epoch.
fn stamp() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

fn save_color_image(image: &egui::ColorImage, path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let [w, h] = image.size;
    let rgba = image
        .pixels
        .iter()
        .flat_map(|c| {
            let [r, g, b, _] = c.to_array();
            [r, g, b, 255]
        })
        .collect();
    render::Image {
        width: w as u32,
        height: h as u32,
        rgba,
    }
    .save_png(path)?;
    Ok(())
}

/// Run the demo with the window (when a display is present): the demo drives the session on
/// a thread, the window shows it on this one and stays open on the result until closed.
/// Closing the window early stops the demo.
pub fn demo(args: &crate::live::demo::DemoArgs) -> anyhow::Result<()> {
    if args.no_window || !display_available() {
        return crate::live::demo::run(args).map(|_| ());
    }
    let (link_tx, link_rx) = mpsc::channel();
    let cancelled = Arc::new(AtomicBool::new(false));
    let log: Arc<Mutex<Vec<String>>> = Arc::default();
    let hooks = crate::live::demo::DemoHooks {
        started: Some(link_tx),
        cancelled: Arc::clone(&cancelled),
        log: Some(Arc::clone(&log)),
    };
    let demo_args = args.clone();
    let worker = std::thread::Builder::new()
        .name("demo".into())
        .spawn(move || crate::live::demo::run_with(&demo_args, hooks))
        .context("starting the demo thread")?;
    let shown = match link_rx.recv() {
        Ok(mut link) => {
            link.log = log;
            open(
                link,
                None,
                args.out.clone(),
                Exit::default(),
                (1280, 800),
                "workstation demo",
            )
        }
        Err(_) => Ok(()), // the demo failed before its session started: its error follows
    };
    cancelled.store(true, Ordering::Relaxed);
    let result = worker
        .join()
        .map_err(|_| anyhow::anyhow!("the demo thread panicked"))?;
    shown?;
    match result {
        Ok(_) => Ok(()),
        Err(e) if e.to_string().starts_with("interrupted") => {
            println!("demo: the window was closed before the end");
            Ok(())
        }
        Err(e) => Err(e),
    }
}
