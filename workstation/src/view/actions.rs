//! What the window does: the panel's and the keys' actions (select, settings, CSG, emboss,
//! save, export, load, screenshot).

use std::path::{Path, PathBuf};
use std::sync::mpsc;

use anyhow::Context as _;
use eframe::egui;
use glam::DVec3;

use super::app::ViewApp;
use super::panel::{self, Action, Pending};
use crate::live::sim::SimCommand;

impl ViewApp {
    pub(super) fn act(&mut self, ctx: &egui::Context, action: Action) {
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
                self.stylus.reset();
            }
        }
    }

    pub(super) fn load(&mut self, path: &Path) {
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
                self.stylus.reset();
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

    pub(super) fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
        if self.shot_path.is_some() {
            return;
        }
        let tx = self.shots.0.clone();
        ctx.request_screenshot(move |image| {
            let _ = tx.send(image);
        });
        self.shot_path = Some(path);
    }

    /// The actions of the keys pressed this frame (none while a text field has the keyboard).
    /// Each key's Ctrl is read from its own event, not from the frame's modifiers: at a low
    /// frame rate a quick Ctrl+E is over (Ctrl up again) before the frame that sees it.
    pub(super) fn keys(&mut self, ctx: &egui::Context) -> Vec<Action> {
        if ctx.egui_wants_keyboard_input() {
            return Vec::new();
        }
        let mut actions = Vec::new();
        let mut quit = false;
        ctx.input(|i| {
            for e in &i.events {
                let egui::Event::Key {
                    key,
                    pressed: true,
                    repeat: false,
                    modifiers,
                    ..
                } = e
                else {
                    continue;
                };
                let number = [
                    egui::Key::Num1,
                    egui::Key::Num2,
                    egui::Key::Num3,
                    egui::Key::Num4,
                    egui::Key::Num5,
                    egui::Key::Num6,
                ]
                .iter()
                .position(|k| k == key);
                match (modifiers.ctrl, key, number) {
                    (false, _, Some(k)) => actions.push(Action::Select(panel::TOOLS[k].0)),
                    (false, egui::Key::F, _) => actions.push(Action::Frame),
                    (true, egui::Key::S, _) => actions.push(Action::SaveScene),
                    (true, egui::Key::E, _) => actions.push(Action::Export),
                    (true, egui::Key::Q, _) => quit = true,
                    (_, egui::Key::F12, _) => actions.push(Action::Screenshot),
                    _ => {}
                }
            }
        });
        if quit {
            self.close(ctx);
        }
        actions
    }
}

/// A timestamp for file names: seconds since the epoch.
fn stamp() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

pub(super) fn save_color_image(image: &egui::ColorImage, path: &Path) -> anyhow::Result<()> {
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
