//! Tools: what a press engages, what each step applies, what a release commits.
//!
//! A button press engages the selected (or next queued) tool at the cursor, a release lets go
//! and **commits** the shape: plastic, the sculpted field becomes the rest state.
//! - `rope`: press anywhere; the rope attaches at the surface point nearest the tip and pulls
//!   the surface along its normal by `k·(tip − picked)·n` (capped at `max_force`); the user
//!   feels the spring to the moving attachment.
//! - `rope_curve`: the tip's path while pressed, projected onto the (rest) surface, becomes the
//!   rope; it pulls by `k·(height of the tip above the surface)`, capped at `max_force`.
//! - `paint`: while pressed and touching, the brush paints at the contact point, its radius
//!   growing with the pressing force.
//! - `probe_push` / `probe_pull`: the shaped probe carves (difference) or, pressed inside the
//!   material, drags it out (union) as it moves; the user feels the probe against the samples.

use glam::DVec3;
use sim_core::probe::ProbePose;
use sim_core::scene::ResampleReport;
use sim_core::tools::paint::{Brush, paint};
use sim_core::tools::{GridTool, ProbeMode, ProbeSculpt, Profile, Rope};

use super::SimCore;
use crate::live::scene_file::ToolKind;
use crate::live::shared::{ForceTool, InputEvent};
use crate::sculpt::script::profile_of;

/// Most waypoints a curve rope keeps.
pub const MAX_CURVE_POINTS: usize = 64;

/// What one stroke did, for progress lines and the summary.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StrokeReport {
    /// 0-based stroke number.
    pub index: usize,
    /// The tool.
    pub tool: ToolKind,
    /// Simulation steps while pressed.
    pub steps: u64,
    /// Largest change of the field value committed at release (m of signed distance).
    pub committed_displacement_m: f64,
    /// Points painted (paint).
    pub painted: usize,
    /// Largest force felt (N).
    pub max_force_n: f64,
    /// What resampling the region did at the commit.
    pub resampled: ResampleReport,
    /// One line for people.
    pub summary: String,
}

pub(super) enum Active {
    Rope {
        rope: Rope,
        picked: DVec3,
        normal: DVec3,
    },
    Paint {
        painted: usize,
    },
    Probe(ProbeSculpt),
    Touch,
}

pub(super) struct Stroke {
    pub(super) tool: ToolKind,
    active: Active,
    steps: u64,
    max_force: f64,
}

impl SimCore {
    /// What the force thread should render now.
    pub fn force_tool(&self) -> ForceTool {
        let t = &self.file.tools;
        let probe = ForceTool::Probe(t.probe);
        match &self.stroke {
            Some(Stroke {
                tool,
                active:
                    Active::Rope {
                        rope,
                        picked,
                        normal,
                    },
                ..
            }) => {
                // A curve rope holds the surface where the tip last passed; a point rope where
                // it was picked.
                let (p, n) = match (tool, rope.path.last()) {
                    (ToolKind::RopeCurve, Some(&last)) => {
                        let field = &self.scene.objects()[self.region_object].field;
                        let n = field.value_and_gradient(last).1.try_normalize();
                        (last, n.unwrap_or(*normal))
                    }
                    _ => (*picked, *normal),
                };
                ForceTool::Rope {
                    anchor: self.attachment(p, n),
                    stiffness: t.rope.stiffness,
                    max_force: t.rope.max_force,
                }
            }
            Some(Stroke {
                active: Active::Probe(_),
                ..
            }) => probe,
            Some(_) => ForceTool::Touch(t.contact),
            // A queued tool is only engaged at its press; until then the selected one is felt
            // (switching the felt model under a resting stylus would kick it).
            None => match self.selected {
                ToolKind::ProbePush | ToolKind::ProbePull => probe,
                _ => ForceTool::Touch(t.contact),
            },
        }
    }

    /// Where the rope holds the surface now: the picked point moved along its normal to the
    /// current zero set.
    fn attachment(&self, picked: DVec3, normal: DVec3) -> DVec3 {
        let d = self
            .scene
            .region()
            .and_then(|r| {
                let m = r.model();
                let spec = m.spec();
                let (c, t) = spec.locate(picked)?;
                let up = |a: usize| c[a] + usize::from(t[a] > 0.5);
                Some(m.value(spec.index(up(0), up(1), up(2))))
            })
            .unwrap_or(0.0);
        picked - normal * d
    }

    /// The surface point nearest `x` on the region's object, with its outward normal. A
    /// projection that lands on an untrusted piece of the zero set (away from the points) is
    /// not the surface: the nearest point of the object is taken instead (once per press, so
    /// a scan is fine).
    fn nearest_surface(&self, x: DVec3) -> (DVec3, DVec3) {
        let o = &self.scene.objects()[self.region_object];
        let pr = o.field.project_to_zero_set(x);
        let p = if pr.trusted {
            pr.point
        } else {
            o.positions
                .iter()
                .copied()
                .min_by(|a, b| a.distance_squared(x).total_cmp(&b.distance_squared(x)))
                .unwrap_or(pr.point)
        };
        let n = o
            .field
            .value_and_gradient(p)
            .1
            .try_normalize()
            .unwrap_or(DVec3::Z);
        (p, n)
    }

    /// Consume one input event (in the order the force thread produced them).
    pub fn input(&mut self, e: &InputEvent) -> anyhow::Result<()> {
        let was = self.last.is_some_and(|l| l.pressed());
        if e.pressed() && !was {
            self.press(e);
        } else if !e.pressed() && was {
            self.release()?;
        }
        if let Some(s) = &mut self.stroke {
            s.max_force = s.max_force.max(e.force.length());
        }
        self.last = Some(*e);
        Ok(())
    }

    fn press(&mut self, e: &InputEvent) {
        let tool = self.queue.pop_front().unwrap_or(self.selected);
        let t = &self.file.tools;
        let active = match tool {
            ToolKind::Rope | ToolKind::RopeCurve => {
                let (picked, normal) = self.nearest_surface(e.position);
                let profile = profile_of(&t.rope.profile, t.rope.table.as_deref())
                    .unwrap_or(Profile::Gaussian);
                Active::Rope {
                    rope: Rope {
                        path: vec![picked],
                        radius: t.rope.radius,
                        strength: 0.0,
                        profile,
                        sheet: None,
                    },
                    picked,
                    normal,
                }
            }
            ToolKind::Paint => Active::Paint { painted: 0 },
            ToolKind::ProbePush | ToolKind::ProbePull => Active::Probe(ProbeSculpt {
                probe: self.probe,
                mode: if tool == ToolKind::ProbePush {
                    ProbeMode::Push
                } else {
                    ProbeMode::Pull
                },
                stiffness: t.probe.sculpt_stiffness,
            }),
            ToolKind::Touch => Active::Touch,
        };
        tracing::debug!(tool = tool.name(), at = ?e.position, "stroke begins");
        self.stroke = Some(Stroke {
            tool,
            active,
            steps: 0,
            max_force: 0.0,
        });
    }

    pub(super) fn release(&mut self) -> anyhow::Result<()> {
        let Some(s) = self.stroke.take() else {
            return Ok(());
        };
        let committed = self.scene.region().map_or(0.0, |r| {
            r.model()
                .displacement()
                .iter()
                .fold(0.0, |a: f64, u| a.max(u.abs()))
        });
        // The band follows the surface, but the region's box does not: a surface carried to
        // its faces is cut flat there.
        let at_edge = self
            .scene
            .region()
            .is_some_and(|r| r.model().zero_set_at_edge());
        let refitted = self.scene.end_stroke()?;
        let resampled = self
            .scene
            .region()
            .map_or_else(ResampleReport::default, |r| r.last_resample());
        let painted = match s.active {
            Active::Paint { painted } => painted,
            _ => 0,
        };
        let index = self.strokes.len();
        if at_edge {
            tracing::warn!(
                committed_mm = committed * 1e3,
                "the stroke reached the edge of the region"
            );
        }
        let summary = match s.tool {
            ToolKind::Paint => format!(
                "{painted} point colourings over {} steps, up to {:.2} N",
                s.steps, s.max_force
            ),
            ToolKind::Touch => format!("touched for {} steps, up to {:.2} N", s.steps, s.max_force),
            _ => format!(
                "{} steps, field changed by up to {:.2} mm and committed at release, {refitted} local fields refitted, up to {:.2} N felt; resampled: {} inserted, {} removed, {} projected",
                s.steps,
                committed * 1e3,
                s.max_force,
                resampled.inserted,
                resampled.removed,
                resampled.projected
            ),
        };
        let summary = if at_edge {
            let (lo, hi) = (self.bounds.0 * 1e3, self.bounds.1 * 1e3);
            format!(
                "{summary}; it reached the edge of the region (box [{:.0}, {:.0}, {:.0}] to \
                 [{:.0}, {:.0}, {:.0}] mm) and is cut flat there: give [region] a larger box",
                lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
            )
        } else {
            summary
        };
        self.strokes.push(StrokeReport {
            index,
            tool: s.tool,
            steps: s.steps,
            committed_displacement_m: committed,
            painted,
            max_force_n: s.max_force,
            resampled,
            summary,
        });
        Ok(())
    }

    /// One simulation step of `dt` with the engaged tool at the newest cursor.
    pub fn step(&mut self, dt: f64) -> anyhow::Result<()> {
        let t = self.file.tools.clone();
        let cursor = self.last;
        let paint_slot = self.visible_slot(self.region_object);
        let mut tool: Option<&dyn GridTool> = None;
        if let (Some(s), Some(e)) = (&mut self.stroke, cursor) {
            s.steps += 1;
            match &mut s.active {
                Active::Rope {
                    rope,
                    picked,
                    normal,
                } => {
                    // Point rope: how far the tip is pulled out along the picked normal. Curve
                    // rope: how far the tip is above the (rest) surface where it is now.
                    let out = if s.tool == ToolKind::RopeCurve {
                        self.scene.objects()[self.region_object]
                            .field
                            .value(e.position)
                    } else {
                        (e.position - *picked).dot(*normal)
                    };
                    let pull = t.rope.stiffness * out;
                    rope.strength = pull.clamp(-t.rope.max_force, t.rope.max_force);
                    if s.tool == ToolKind::RopeCurve && rope.path.len() < MAX_CURVE_POINTS {
                        // The tip's path projected onto the rest surface becomes the rope.
                        let o = &self.scene.objects()[self.region_object];
                        let pr = o.field.project_to_zero_set(e.position);
                        let c = pr.point;
                        if pr.trusted
                            && c.is_finite()
                            && rope
                                .path
                                .last()
                                .is_some_and(|l| l.distance(c) > t.rope.radius * 0.5)
                        {
                            rope.path.push(c);
                        }
                    }
                    tool = Some(&*rope);
                }
                Active::Paint { painted } => {
                    if let Some((c, _)) = e.contact {
                        let brush = Brush {
                            color: t.paint.color,
                            radius: t.paint.radius,
                            radius_per_newton: t.paint.radius_per_newton,
                            max_radius: t.paint.max_radius,
                            falloff: profile_of(&t.paint.falloff, None)
                                .unwrap_or(Profile::Spherical),
                        };
                        let obj = self
                            .scene
                            .object_mut(self.region_object)
                            .expect("the region's object exists");
                        let r =
                            paint(&brush, c, e.force.length(), &obj.positions, &mut obj.colors)?;
                        *painted += r.painted;
                        // Tell the renderer's snapshots which points may have changed colour:
                        // the region's points when the brush is inside its box, else all.
                        let obj = &self.scene.objects()[self.region_object];
                        let (lo, hi) = (c - r.radius, c + r.radius);
                        let near = |i: usize| obj.positions[i].distance(c) <= r.radius;
                        match self.scene.region() {
                            Some(reg)
                                if lo.cmpge(self.bounds.0).all()
                                    && hi.cmple(self.bounds.1).all() =>
                            {
                                let near = reg
                                    .points_inside()
                                    .iter()
                                    .map(|&i| i as usize)
                                    .filter(|&i| near(i));
                                self.publisher.mark_many(paint_slot, near);
                            }
                            _ => {
                                let near = (0..obj.positions.len()).filter(|&i| near(i));
                                self.publisher.mark_many(paint_slot, near);
                            }
                        }
                    }
                }
                Active::Probe(p) => {
                    p.probe.set_pose(ProbePose {
                        position: e.position,
                        orientation: e.orientation,
                    })?;
                    tool = Some(&*p);
                }
                Active::Touch => {}
            }
        }
        match tool {
            Some(t) => self.scene.step_field(dt, &[t])?,
            None => self.scene.step_field(dt, &[])?,
        };
        self.steps += 1;
        Ok(())
    }

    /// Whether a stroke is engaged.
    pub fn engaged(&self) -> bool {
        self.stroke.is_some()
    }

    /// Let go of an engaged stroke as if the button were released (the session dropped).
    pub fn release_engaged(&mut self) -> anyhow::Result<()> {
        if let Some(mut e) = self.last {
            e.buttons &= !1;
            self.input(&e)?;
        }
        Ok(())
    }
}
