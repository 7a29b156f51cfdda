//! A scene's scripted phases, shared by `demo` and `run`: the fake hand's path that performs
//! its strokes ([`hand_path`], written for a server by [`write_hand_path`]) and the driver that
//! runs the phases against a workstation ([`drive_phases`]).

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glam::{DVec3, Vec3};
use serde::Serialize;

use super::Workstation;
use super::scene_file::SceneFile;
use super::sim::SimReport;

/// What one phase did.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseReport {
    /// As in the scene.
    pub name: String,
    /// `stroke:<tool>` or `op:<kind>`.
    pub kind: String,
    /// What it did.
    pub summary: String,
    /// Wall time (s).
    pub seconds: f64,
}

/// The fake hand's path for the scene's strokes, in the device frame: rest lifted above the
/// first stroke for `lead_in_s`, then per stroke: travel (button up, via points lifted away
/// from the region's centre so the hand does not cut through the object), press at the first
/// waypoint, follow the waypoints over `seconds`, release, rest. Ends with a long rest (the
/// server loops recorded paths).
pub fn hand_path(scene: &SceneFile, lead_in_s: f64) -> Vec<(f32, Vec3, u16)> {
    let t = scene.device.transform();
    let (lo, hi) = (DVec3::from(scene.region.min), DVec3::from(scene.region.max));
    let centre = 0.5 * (lo + hi);
    let lift = |p: DVec3| centre + (p - centre) * 1.6;
    let dev = |p: DVec3| t.point_to_device(p).as_vec3();
    let strokes: Vec<_> = scene
        .phase
        .iter()
        .filter_map(|p| p.stroke.as_ref())
        .collect();
    let mut out = Vec::new();
    let Some(first) = strokes.first() else {
        return vec![(0.0, dev(lift(lo.max(hi))), 0)];
    };
    let mut time = 0.0f64;
    let mut at = lift(DVec3::from(first.path[0]));
    let mut push = |time: f64, p: DVec3, b: u16| out.push((time as f32, dev(p), b));
    push(0.0, at, 0);
    time += lead_in_s;
    push(time, at, 0);
    for s in strokes {
        let start = DVec3::from(s.path[0]);
        time += 0.5 * s.travel_s;
        push(time, lift(start), 0);
        time += 0.5 * s.travel_s;
        push(time, start, 0);
        time += 0.1;
        push(time, start, 1);
        let n = s.path.len();
        let dt = if n > 1 {
            s.seconds / (n - 1) as f64
        } else {
            s.seconds
        };
        for (k, p) in s.path.iter().enumerate().skip(usize::from(n > 1)) {
            time += dt;
            // Held until the next point: the last waypoint releases.
            push(time, DVec3::from(*p), u16::from(k + 1 < n));
        }
        let end = DVec3::from(s.path[n - 1]);
        if n == 1 {
            time += 0.05;
            push(time, end, 0);
        }
        time += s.rest_s.max(0.05);
        at = lift(end);
        push(time, at, 0);
    }
    push(time + 1e5, at, 0);
    out
}

/// Write `hand_path` as the server's path file (`t x y z buttons` per line).
pub fn write_hand_path(path: &Path, points: &[(f32, Vec3, u16)]) -> anyhow::Result<()> {
    let mut text = String::from("# t_s x y z buttons (workstation hand-path)\n");
    for (t, p, b) in points {
        text.push_str(&format!("{t} {} {} {} {b}\n", p.x, p.y, p.z));
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Run the scene's phases in order: the strokes' tools were queued for the button presses when
/// the simulation started ([`crate::live::sim::SimCore::new`]), each stroke phase ends when the
/// simulation reports its release, each operation runs on the simulation thread. `progress` is
/// called as each phase ends.
pub fn drive_phases(
    ws: &Workstation,
    scene: &SceneFile,
    deadline: Instant,
    cancelled: impl Fn() -> bool,
    mut progress: impl FnMut(usize, &PhaseReport),
) -> anyhow::Result<Vec<PhaseReport>> {
    let mut reports = Vec::new();
    let mut t0 = Instant::now();
    for (i, phase) in scene.phase.iter().enumerate() {
        let report = if let Some(stroke) = &phase.stroke {
            let done = loop {
                anyhow::ensure!(!cancelled(), "interrupted during phase `{}`", phase.name);
                anyhow::ensure!(
                    Instant::now() < deadline,
                    "phase `{}`: the stroke did not end before the deadline (is the device following the hand path? connected: {})",
                    phase.name,
                    ws.connected()
                );
                match ws.next_report(Duration::from_millis(100)) {
                    Some(SimReport::Stroke(s)) => break s,
                    Some(SimReport::Failed(e)) => anyhow::bail!("simulation failed: {e}"),
                    None => {}
                }
            };
            PhaseReport {
                name: phase.name.clone(),
                kind: format!("stroke:{}", stroke.tool.name()),
                summary: done.summary,
                seconds: t0.elapsed().as_secs_f64(),
            }
        } else if let Some(op) = &phase.op {
            let (kind, summary) = ws
                .run_op(op)
                .with_context(|| format!("phase `{}`", phase.name))?;
            PhaseReport {
                name: phase.name.clone(),
                kind: format!("op:{kind}"),
                summary,
                seconds: t0.elapsed().as_secs_f64(),
            }
        } else {
            continue;
        };
        progress(i, &report);
        reports.push(report);
        t0 = Instant::now();
    }
    Ok(reports)
}
