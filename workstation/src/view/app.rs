//! The window's app: its state, the per-frame update (panel, scene view, exit), the status
//! lines and the `--state` JSON.

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use eframe::egui::{self, Sense};
use glam::DVec3;

use super::orbit::Orbit;
use super::panel::{Panel, Pending};
use super::plots::{History, Sample};
use super::scene::{Gpu, save_color_image};
use super::stylus::{self, MouseStylus};
use super::{Exit, Link, Starter};
use crate::live::Workstation;
use crate::live::frames::{self, SplatCache};
use crate::live::points::ChunkedPoints;
use crate::live::scene_file::ToolKind;
use crate::live::sim::SimReport;
use crate::live::sim::{Settings, SimCommand};

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
    /// Where the centre of the points is seen, in window pixels.
    object_centre: Option<[f32; 2]>,
    /// Where the centre of the sculpting region is seen, in window pixels.
    region_centre: Option<[f32; 2]>,
    /// The mouse as the stylus (absent when a device drives the cursor).
    mouse: Option<MouseState>,
    /// Other stations of a shared scene (`--share`): name and where its cursor is seen, in
    /// window pixels.
    others: Vec<(String, Option<[f32; 2]>)>,
    messages: &'a VecDeque<String>,
}

/// The window's app: the session it shows, the camera, the panel, the plots and when to exit.
/// The mouse stylus in `--state` JSON (scene metres).
#[derive(Debug, serde::Serialize)]
struct MouseState {
    /// The selected tool's depth (see [`super::stylus`]).
    tool_depth_m: f64,
    /// The surface under the mouse.
    hit: Option<[f64; 3]>,
    /// The surface point the press in progress grabbed.
    grabbed: Option<[f64; 3]>,
    /// Where the mouse is, window pixels (the one the hit is under).
    pointer: Option<[f32; 2]>,
    /// The cursor the mouse thread streams, and its buttons.
    cursor: [f64; 3],
    buttons: u16,
}

/// The mean of `points`, `None` when there are none.
fn centroid(points: &ChunkedPoints) -> Option<DVec3> {
    (!points.is_empty()).then(|| points.positions().sum::<DVec3>() / points.len() as f64)
}

pub(super) struct ViewApp {
    pub(super) link: Link,
    pub(super) owned: Option<(Workstation, Starter)>,
    pub(super) gpu: Gpu,
    pub(super) splats: SplatCache,
    pub(super) orbit: Option<Orbit>,
    /// The mouse as the stylus (used when the mouse is the device).
    pub(super) stylus: MouseStylus,
    /// The points' typical spacing for picking them, and the point count it was measured at.
    pub(super) pick_spacing: Option<(usize, f64)>,
    /// Where the mouse was over the view this frame, window pixels.
    pub(super) pointer: Option<egui::Pos2>,
    pub(super) panel: Panel,
    pub(super) pending: Vec<Pending>,
    pub(super) messages: VecDeque<String>,
    pub(super) history: History,
    pub(super) started: Instant,
    pub(super) last_frame: Instant,
    pub(super) frames: u64,
    pub(super) fps: f64,
    pub(super) exit: Exit,
    pub(super) shots: (
        mpsc::Sender<Arc<egui::ColorImage>>,
        mpsc::Receiver<Arc<egui::ColorImage>>,
    ),
    pub(super) shot_path: Option<PathBuf>,
    pub(super) closing: bool,
    pub(super) last_state: Instant,
    pub(super) tool_rects: BTreeMap<&'static str, egui::Rect>,
    pub(super) view_rect: egui::Rect,
    pub(super) failed: Arc<Mutex<Option<String>>>,
    pub(super) stopped_said: bool,
}

impl ViewApp {
    pub(super) fn new(
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
            stylus: MouseStylus::default(),
            pick_spacing: None,
            pointer: None,
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

    pub(super) fn panel_for(link: &Link, out: &Path, can_load: bool) -> Panel {
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

    pub(super) fn say(&mut self, line: impl Into<String>) {
        let line = line.into();
        tracing::info!("{line}");
        self.messages.push_back(line);
        while self.messages.len() > 8 {
            self.messages.pop_front();
        }
    }

    pub(super) fn send(&mut self, cmd: SimCommand) {
        if self.link.commands.send(cmd).is_err() {
            self.say("the simulation has stopped");
        }
    }

    pub(super) fn out_dir(&self) -> PathBuf {
        PathBuf::from(&self.panel.out_dir)
    }
    pub(super) fn poll(&mut self, ctx: &egui::Context) {
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
        // What each stroke did (the demo's driver reads these itself: then nothing is owned).
        if let Some((ws, _)) = &self.owned {
            while let Some(r) = ws.next_report(std::time::Duration::ZERO) {
                lines.push(match r {
                    SimReport::Stroke(s) => format!("{}: {}", s.tool.name(), s.summary),
                    SimReport::Failed(e) => format!("the simulation stopped: {e}"),
                });
            }
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

    pub(super) fn close(&mut self, ctx: &egui::Context) {
        self.closing = true;
        self.write_state();
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
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
            points: snap.as_ref().map_or(0, |s| s.points.len()),
            tool_buttons: self.tool_rects.iter().map(|(k, r)| (*k, px(r))).collect(),
            view: px(&self.view_rect),
            object_centre: snap
                .as_ref()
                .and_then(|s| centroid(&s.points))
                .and_then(|c| self.seen(c)),
            region_centre: snap
                .as_ref()
                .and_then(|s| s.region)
                .and_then(|(lo, hi)| self.seen(0.5 * (lo + hi))),
            mouse: self.link.mouse.as_ref().map(|hand| {
                let (cursor, buttons) = hand.get();
                let tool = snap
                    .as_ref()
                    .and_then(|s| s.tool)
                    .unwrap_or(self.panel.tool);
                MouseState {
                    tool_depth_m: self.stylus.depth(tool),
                    hit: self.stylus.hit().map(|h| h.point.to_array()),
                    grabbed: self.stylus.grabbed().map(|h| h.point.to_array()),
                    pointer: self.pointer.map(|p| [p.x, p.y]),
                    cursor: cursor.to_array(),
                    buttons,
                }
            }),
            others: self.link.remote.as_ref().map_or_else(Vec::new, |r| {
                r.other_cursors(std::time::Duration::from_secs(1))
                    .into_iter()
                    .map(|(name, at)| (name, self.seen(DVec3::from(at))))
                    .collect()
            }),
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

    /// Where `p` is seen in the window (pixels), if in front of the camera.
    fn seen(&self, p: DVec3) -> Option<[f32; 2]> {
        let r = self.view_rect;
        let (x, y) = self
            .orbit?
            .project(p, r.width() as f64, r.height() as f64)?;
        Some([r.min.x + x as f32, r.min.y + y as f32])
    }

    fn status(&self, ui: &mut egui::Ui) {
        let s = &self.link.shared;
        let connected = s.net.connected.load(Ordering::Relaxed);
        ui.label(format!("cursor: {}", self.link.source));
        let why = s.net.connect_error.load_full();
        ui.label(if s.stopping() {
            why.map_or("session ended".to_owned(), |w| format!("stopped: {w}"))
        } else if connected {
            format!(
                "connected · sessions {} · cursors {}",
                s.net.sessions.load(Ordering::Relaxed),
                s.net.cursors.load(Ordering::Relaxed)
            )
        } else if let Some(why) = why {
            format!("not connected: {why} (retrying)")
        } else {
            "waiting for the server …".to_owned()
        });
        let points = s.render.load().as_ref().map_or(0, |r| r.points.len());
        ui.label(format!(
            "{points} points · {:.0} frames/s · force loop {:.0} Hz · simulation {:.0} Hz",
            self.fps,
            s.force_loop.rate_hz(),
            s.sim_loop.rate_hz()
        ));
        if let Some(r) = &self.link.remote {
            let others = r.others_heard(std::time::Duration::from_secs(1));
            ui.label(format!(
                "shared scene: {} · version {} · took {}, proposed {} · with {}",
                if r.joined.load(Ordering::Relaxed) {
                    "joined"
                } else {
                    "joining …"
                },
                r.version.load(Ordering::Relaxed),
                r.adopted.load(Ordering::Relaxed),
                r.proposed.load(Ordering::Relaxed),
                if others.is_empty() {
                    "nobody else".to_owned()
                } else {
                    others.join(", ")
                }
            ));
        }
    }

    /// The scene view: handle the mouse, then draw.
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
        let mut orbit = self.orbit.unwrap_or_else(|| {
            let (lo, hi) = frames::scene_bounds(&snap);
            Orbit::framing(lo, hi, DVec3::from(self.link.scene.render.view_dir))
        });
        self.camera_input(ui, &response, &mut orbit, &snap);
        self.mouse_input(ui, &response, &orbit, rect, &snap);
        self.orbit = Some(orbit);

        // Draw.
        let camera = orbit.camera();
        let overlay = frames::overlay(&snap, &self.link.shared);
        match self
            .gpu
            .draw(size, &mut self.splats, &snap, &overlay, &camera)
        {
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
        // Other stations of a shared scene: their cursors, named.
        if let Some(remote) = &self.link.remote {
            for (name, at) in remote.other_cursors(std::time::Duration::from_secs(1)) {
                let Some((x, y)) =
                    orbit.project(DVec3::from(at), rect.width() as f64, rect.height() as f64)
                else {
                    continue;
                };
                let p = rect.min + egui::vec2(x as f32, y as f32);
                if !rect.contains(p) {
                    continue;
                }
                let colour = egui::Color32::from_rgb(255, 170, 40);
                ui.painter()
                    .circle_stroke(p, 7.0, egui::Stroke::new(2.0, colour));
                ui.painter().text(
                    p + egui::vec2(10.0, -10.0),
                    egui::Align2::LEFT_BOTTOM,
                    name,
                    egui::FontId::proportional(14.0),
                    colour,
                );
            }
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_millis(30));
        }
        let hint = if self.link.mouse.is_some() {
            let tool = snap.tool.unwrap_or(self.panel.tool);
            format!(
                "mouse = stylus · {}\nright-drag orbit · middle-drag pan · Ctrl+wheel zoom · F frame",
                stylus::hint(tool, self.stylus.depth(tool))
            )
        } else {
            "right-drag orbit · middle-drag pan · wheel zoom · F frame".to_owned()
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
