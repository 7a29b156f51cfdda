//! The control panel (egui): tool choice and settings, material and integrator, operations,
//! files, connection status and live plots. It edits a copy of the session's [`Settings`] and
//! sends changes to the simulation thread as commands; answers come back on channels and are
//! polled each frame ([`Pending`]), so the window never waits for the simulation.

use std::path::PathBuf;
use std::sync::mpsc;

use eframe::egui::{self, ComboBox, DragValue, Slider, Ui};
use sim_core::csg::CsgOp;

use crate::live::scene_file::{ProbeDirection, ToolKind};
use crate::live::sim::Settings;

/// The tools the panel offers, in its order, with their labels.
pub const TOOLS: [(ToolKind, &str); 6] = [
    (ToolKind::Touch, "Touch"),
    (ToolKind::Rope, "Rope (point)"),
    (ToolKind::RopeCurve, "Rope (curve)"),
    (ToolKind::Paint, "Paint"),
    (ToolKind::ProbePush, "Probe: carve"),
    (ToolKind::ProbePull, "Probe: pull"),
];

/// Profiles of the rope and the paint brush.
const PROFILES: [&str; 3] = ["gaussian", "constant", "spherical"];
/// Integrators of the region.
const INTEGRATORS: [&str; 3] = ["symplectic_euler", "forward_euler", "backward_euler"];

/// A command's answer not yet back: polled each frame, turned into a message line.
pub struct Pending {
    what: String,
    poll: Box<dyn FnMut() -> Option<Result<String, String>>>,
}

impl std::fmt::Debug for Pending {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pending").field("what", &self.what).finish()
    }
}

impl Pending {
    /// Wait for `rx` (without blocking); `done` says what a success did.
    pub fn new<T: 'static>(
        what: impl Into<String>,
        rx: mpsc::Receiver<anyhow::Result<T>>,
        done: impl Fn(T) -> String + 'static,
    ) -> Self {
        Self {
            what: what.into(),
            poll: Box::new(move || match rx.try_recv() {
                Ok(Ok(v)) => Some(Ok(done(v))),
                Ok(Err(e)) => Some(Err(format!("{e:#}"))),
                Err(mpsc::TryRecvError::Empty) => None,
                Err(mpsc::TryRecvError::Disconnected) => {
                    Some(Err("the simulation has stopped".into()))
                }
            }),
        }
    }

    /// What it waits for.
    pub fn what(&self) -> &str {
        &self.what
    }

    /// The answer, once it is there.
    pub fn poll(&mut self) -> Option<Result<String, String>> {
        (self.poll)()
    }
}

/// What the panel asks the window to do this frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Select a tool.
    Select(ToolKind),
    /// Apply the tool settings (live, while a slider moves).
    ApplyTools,
    /// Apply material, integrator and step (reopens the region).
    ApplyMaterial,
    /// Combine a primitive at the cursor.
    Csg {
        /// The operation.
        op: CsgOp,
        /// `sphere` or `box`.
        shape: &'static str,
        /// Radius or half size (m).
        size: f64,
    },
    /// Emboss (depth > 0) or engrave (depth < 0) the image at the contact point.
    Emboss {
        /// The PNG.
        image: PathBuf,
        /// Displacement at white (m).
        depth: f64,
        /// Side of the square the image covers (m).
        size: f64,
    },
    /// Save a scene that reloads this model.
    SaveScene,
    /// Export points and the meshed surface.
    Export,
    /// Save a screenshot of the window.
    Screenshot,
    /// Load another scene.
    Load(PathBuf),
    /// Frame the scene.
    Frame,
}

/// The panel's own state: the edited settings and the operation fields.
#[derive(Debug)]
pub struct Panel {
    /// Settings as edited (sent with [`Action::ApplyTools`] / [`Action::ApplyMaterial`]).
    pub settings: Settings,
    /// The tool shown as selected.
    pub tool: ToolKind,
    csg_op: CsgOp,
    csg_shape: &'static str,
    csg_size_mm: f64,
    emboss_image: String,
    emboss_depth_mm: f64,
    emboss_size_mm: f64,
    load_path: String,
    /// Where saves, exports and screenshots go.
    pub out_dir: String,
    /// Whether loading another scene is offered (not while a demo drives the session).
    pub can_load: bool,
}

impl Panel {
    /// For a session's settings and selected tool.
    pub fn new(settings: Settings, tool: ToolKind, out_dir: PathBuf, emboss_image: String) -> Self {
        Self {
            settings,
            tool,
            csg_op: CsgOp::Difference,
            csg_shape: "sphere",
            csg_size_mm: 8.0,
            emboss_image,
            emboss_depth_mm: 1.0,
            emboss_size_mm: 30.0,
            load_path: String::new(),
            out_dir: out_dir.display().to_string(),
            can_load: true,
        }
    }

    /// Tool buttons: `(tool, label)`; the window records where each was drawn.
    pub fn tools(
        &mut self,
        ui: &mut Ui,
        mut placed: impl FnMut(ToolKind, egui::Rect),
    ) -> Vec<Action> {
        let mut actions = Vec::new();
        ui.heading("Tool");
        ui.horizontal_wrapped(|ui| {
            for (k, (tool, label)) in TOOLS.iter().enumerate() {
                let r = ui
                    .selectable_value(&mut self.tool, *tool, *label)
                    .on_hover_text(format!("key {}", k + 1));
                placed(*tool, r.rect);
                if r.clicked() {
                    actions.push(Action::Select(*tool));
                }
            }
        });
        actions
    }

    /// Tool settings, material, operations and files.
    pub fn settings(&mut self, ui: &mut Ui, contact: Option<glam::DVec3>) -> Vec<Action> {
        let mut actions = Vec::new();
        let mut tools_changed = false;
        let t = &mut self.settings.tools;
        egui::CollapsingHeader::new("Tool settings")
            .default_open(true)
            .show(ui, |ui| {
                let mm =
                    |ui: &mut Ui, v: &mut f64, range: std::ops::RangeInclusive<f64>, text: &str| {
                        let mut x = *v * 1e3;
                        let r = ui.add(Slider::new(&mut x, range).text(text).suffix(" mm"));
                        if r.changed() {
                            *v = x * 1e-3;
                        }
                        r.changed()
                    };
                match self.tool {
                    ToolKind::Paint => {
                        ui.horizontal(|ui| {
                            ui.label("brush colour");
                            tools_changed |=
                                ui.color_edit_button_srgb(&mut t.paint.color).changed();
                        });
                        tools_changed |= mm(ui, &mut t.paint.radius, 0.5..=20.0, "brush size");
                        tools_changed |=
                            mm(ui, &mut t.paint.max_radius, 0.5..=40.0, "largest size");
                        t.paint.max_radius = t.paint.max_radius.max(t.paint.radius);
                        tools_changed |= ui
                            .add(
                                Slider::new(&mut t.paint.radius_per_newton, 0.0..=0.02)
                                    .text("growth (m/N)"),
                            )
                            .changed();
                        tools_changed |= profile_box(ui, "falloff", &mut t.paint.falloff);
                    }
                    ToolKind::Rope | ToolKind::RopeCurve => {
                        tools_changed |= mm(ui, &mut t.rope.radius, 2.0..=50.0, "reach");
                        tools_changed |= ui
                            .add(
                                Slider::new(&mut t.rope.stiffness, 5.0..=500.0)
                                    .logarithmic(true)
                                    .text("spring (N/m)"),
                            )
                            .changed();
                        tools_changed |= ui
                            .add(
                                Slider::new(&mut t.rope.max_force, 0.2..=10.0)
                                    .text("max force (N)"),
                            )
                            .changed();
                        tools_changed |= profile_box(ui, "profile", &mut t.rope.profile);
                    }
                    ToolKind::ProbePush | ToolKind::ProbePull => {
                        let [a, b, c] = &mut t.probe.semi_axes;
                        tools_changed |= mm(ui, a, 1.0..=30.0, "semi-axis x");
                        tools_changed |= mm(ui, b, 1.0..=30.0, "semi-axis y");
                        tools_changed |= mm(ui, c, 1.0..=30.0, "semi-axis z");
                        if ui.button("make it a sphere").clicked() {
                            t.probe.semi_axes = [*a; 3];
                            tools_changed = true;
                        }
                        let d = &mut t.probe.direction;
                        ComboBox::from_label("force direction")
                            .selected_text(match d {
                                ProbeDirection::SurfaceNormal => "surface normals",
                                ProbeDirection::ProbeNormal => "probe normals",
                            })
                            .show_ui(ui, |ui| {
                                tools_changed |= ui
                                    .selectable_value(
                                        d,
                                        ProbeDirection::SurfaceNormal,
                                        "surface normals",
                                    )
                                    .changed();
                                tools_changed |= ui
                                    .selectable_value(
                                        d,
                                        ProbeDirection::ProbeNormal,
                                        "probe normals",
                                    )
                                    .changed();
                            });
                        tools_changed |= ui
                            .add(
                                Slider::new(&mut t.probe.sculpt_stiffness, 10.0..=2000.0)
                                    .logarithmic(true)
                                    .text("sculpt spring (N/m)"),
                            )
                            .changed();
                    }
                    ToolKind::Touch => {}
                }
                ui.label("touch");
                tools_changed |= ui
                    .add(
                        Slider::new(&mut t.contact.stiffness, 50.0..=2000.0)
                            .logarithmic(true)
                            .text("stiffness (N/m)"),
                    )
                    .changed();
                tools_changed |= ui
                    .add(Slider::new(&mut t.contact.damping, 0.0..=5.0).text("damping (N·s/m)"))
                    .changed();
                tools_changed |= ui
                    .add(Slider::new(&mut t.contact.friction, 0.0..=1.0).text("friction"))
                    .changed();
            });
        if tools_changed {
            actions.push(Action::ApplyTools);
        }

        egui::CollapsingHeader::new("Material and integrator").show(ui, |ui| {
            let m = &mut self.settings.material;
            egui::Grid::new("material").num_columns(2).show(ui, |ui| {
                ui.label("mass (kg)");
                ui.add(DragValue::new(&mut m.mass).speed(1e-5).range(1e-6..=1.0));
                ui.end_row();
                ui.label("stiffness (N/m)");
                ui.add(DragValue::new(&mut m.stiffness).speed(0.1).range(0.0..=1e4));
                ui.end_row();
                ui.label("damping (N·s/m)");
                ui.add(
                    DragValue::new(&mut m.damping)
                        .speed(0.01)
                        .range(0.0..=100.0),
                );
                ui.end_row();
                ui.label("anchor (N/m)");
                ui.add(DragValue::new(&mut m.anchor).speed(1.0).range(0.0..=1e5));
                ui.end_row();
                ui.label("integrator");
                ComboBox::from_id_salt("integrator")
                    .selected_text(self.settings.integrator.as_str())
                    .show_ui(ui, |ui| {
                        for i in INTEGRATORS {
                            ui.selectable_value(&mut self.settings.integrator, i.to_owned(), i);
                        }
                    });
                ui.end_row();
                ui.label("step (ms)");
                let mut ms = self.settings.dt * 1e3;
                if ui
                    .add(DragValue::new(&mut ms).speed(0.05).range(0.1..=10.0))
                    .changed()
                {
                    self.settings.dt = ms * 1e-3;
                }
                ui.end_row();
            });
            if ui
                .button("Apply")
                .on_hover_text("reopens the sculpting region over the current shape")
                .clicked()
            {
                actions.push(Action::ApplyMaterial);
            }
        });

        egui::CollapsingHeader::new("Operations").show(ui, |ui| {
            ui.label("CSG with a primitive at the cursor");
            ui.horizontal(|ui| {
                ComboBox::from_id_salt("csg op")
                    .selected_text(format!("{:?}", self.csg_op).to_lowercase())
                    .show_ui(ui, |ui| {
                        for op in [CsgOp::Difference, CsgOp::Union, CsgOp::Intersection] {
                            ui.selectable_value(
                                &mut self.csg_op,
                                op,
                                format!("{op:?}").to_lowercase(),
                            );
                        }
                    });
                ComboBox::from_id_salt("csg shape")
                    .selected_text(self.csg_shape)
                    .show_ui(ui, |ui| {
                        ui.selectable_value(&mut self.csg_shape, "sphere", "sphere");
                        ui.selectable_value(&mut self.csg_shape, "box", "box");
                    });
            });
            ui.add(
                Slider::new(&mut self.csg_size_mm, 1.0..=40.0)
                    .text("size")
                    .suffix(" mm"),
            );
            if ui.button("Apply at the cursor").clicked() {
                actions.push(Action::Csg {
                    op: self.csg_op,
                    shape: self.csg_shape,
                    size: self.csg_size_mm * 1e-3,
                });
            }
            ui.separator();
            ui.label("Emboss / engrave an image (PNG) at the contact point");
            ui.text_edit_singleline(&mut self.emboss_image);
            ui.add(
                Slider::new(&mut self.emboss_depth_mm, -3.0..=3.0)
                    .text("depth (− engraves)")
                    .suffix(" mm"),
            );
            ui.add(
                Slider::new(&mut self.emboss_size_mm, 5.0..=100.0)
                    .text("image size")
                    .suffix(" mm"),
            );
            let can = contact.is_some() && !self.emboss_image.is_empty();
            if ui
                .add_enabled(can, egui::Button::new("Apply at the contact"))
                .on_disabled_hover_text("touch the surface and name a PNG first")
                .clicked()
            {
                actions.push(Action::Emboss {
                    image: PathBuf::from(&self.emboss_image),
                    depth: self.emboss_depth_mm * 1e-3,
                    size: self.emboss_size_mm * 1e-3,
                });
            }
        });

        egui::CollapsingHeader::new("Files").show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.label("out");
                ui.text_edit_singleline(&mut self.out_dir);
            });
            ui.horizontal(|ui| {
                if ui.button("Save scene").on_hover_text("Ctrl+S").clicked() {
                    actions.push(Action::SaveScene);
                }
                if ui
                    .button("Export PLY/OBJ/STL")
                    .on_hover_text("Ctrl+E")
                    .clicked()
                {
                    actions.push(Action::Export);
                }
                if ui.button("Screenshot").on_hover_text("F12").clicked() {
                    actions.push(Action::Screenshot);
                }
            });
            if self.can_load {
                ui.horizontal(|ui| {
                    ui.text_edit_singleline(&mut self.load_path)
                        .on_hover_text("a scene file (.toml), or a point or mesh file to sculpt");
                    if ui.button("Load").clicked() && !self.load_path.is_empty() {
                        actions.push(Action::Load(PathBuf::from(&self.load_path)));
                    }
                });
            }
        });
        actions
    }
}

fn profile_box(ui: &mut Ui, label: &str, value: &mut String) -> bool {
    let mut changed = false;
    ComboBox::from_label(label)
        .selected_text(value.as_str())
        .show_ui(ui, |ui| {
            for p in PROFILES {
                changed |= ui.selectable_value(value, p.to_owned(), p).changed();
            }
        });
    changed
}
