//! The check's report: the device, every verdict, the measurements, the workspace and the
//! scene transform; written as JSON (`--out`) and printed as a readable summary.

use std::fmt::Write as _;

use glam::DVec3;
use serde::Serialize;

use super::calibration::{self, Aabb, Fit, SceneTransform};
use super::force::ForceSummary;
use super::read::ReadSummary;
use super::{Item, Status};
use crate::config::DeviceKind;
use crate::device::DeviceInfo;

/// The device as the check saw it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DeviceReport {
    /// Backend (`fake`, `replay`, `hid`, `openhaptics`, `dhd`).
    pub kind: String,
    /// What the device calls itself.
    pub name: String,
    /// Degrees of freedom sensed.
    pub dof_input: u8,
    /// Degrees of freedom actuated.
    pub dof_output: u8,
    /// The device's own force limit, N.
    pub max_force_n: f32,
    /// The device's stiffness limit, N/m.
    pub max_stiffness_n_per_m: f32,
    /// The frame's axes in words.
    pub frame: String,
}

/// The workspace declared and seen, and the transforms for `--region`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Workspace {
    /// What the device declares, m.
    pub declared: Aabb,
    /// The position range read, m (`None`: nothing read).
    pub seen: Option<Aabb>,
    /// Scene transforms onto the region: from the declared box, and from the range seen when
    /// it spans at least 2 cm on every axis.
    pub transforms: Vec<SceneTransform>,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// `haptics-server check` and its version.
    pub tool: String,
    /// Every verdict passed, warned or was skipped; no failure.
    pub passed: bool,
    /// The device.
    pub device: DeviceReport,
    /// Verdicts, in order.
    pub checks: Vec<Item>,
    /// The read phase.
    pub read: ReadSummary,
    /// The force test, when run.
    pub force_test: Option<ForceSummary>,
    /// Workspace and calibration.
    pub workspace: Workspace,
}

/// An `f32` as the decimal it was written as (0.08f32 → 0.08, not 0.0799999982), so the
/// printed transform reads like the figures it came from.
fn widen(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(f64::from(v))
}

/// The smallest extent per axis for a seen range to be worth a transform, m.
pub const MIN_SEEN_EXTENT_M: f64 = 0.02;

/// The workspace section: `region` adds transforms.
pub fn workspace(
    kind: DeviceKind,
    info: &DeviceInfo,
    read: &ReadSummary,
    region: Option<Aabb>,
    fit: Fit,
) -> Workspace {
    let declared = Aabb::new(
        DVec3::from(info.workspace_min.to_array().map(widen)),
        DVec3::from(info.workspace_max.to_array().map(widen)),
    );
    let seen = (read.readings > 0).then(|| {
        Aabb::new(
            DVec3::from(read.position_min.map(widen)),
            DVec3::from(read.position_max.map(widen)),
        )
    });
    let frame = calibration::frame(kind);
    let mut transforms = Vec::new();
    if let Some(region) = region {
        transforms.push(calibration::transform(
            "declared", declared, &frame, region, fit,
        ));
        if let Some(s) = seen {
            let ext = DVec3::from(s.max) - DVec3::from(s.min);
            if ext.min_element() >= MIN_SEEN_EXTENT_M {
                transforms.push(calibration::transform("seen", s, &frame, region, fit));
            }
        }
    }
    Workspace {
        declared,
        seen,
        transforms,
    }
}

impl Report {
    /// Assemble; `passed` is derived from the items.
    pub fn new(
        device: DeviceReport,
        checks: Vec<Item>,
        read: ReadSummary,
        force_test: Option<ForceSummary>,
        workspace: Workspace,
    ) -> Self {
        Self {
            tool: format!("haptics-server check {}", env!("CARGO_PKG_VERSION")),
            passed: checks.iter().all(|i| i.status != Status::Fail),
            device,
            checks,
            read,
            force_test,
            workspace,
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }

    /// The readable summary.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let d = &self.device;
        let _ = writeln!(
            s,
            "device: {} ({}), {}-DOF in / {}-DOF force out, {:.1} N, {:.0} N/m",
            d.name, d.kind, d.dof_input, d.dof_output, d.max_force_n, d.max_stiffness_n_per_m
        );
        let _ = writeln!(s, "frame:  {}", d.frame);
        for item in &self.checks {
            // Multi-line details (one line per axis) continue under the first.
            let detail = item.detail.replace('\n', &format!("\n{:23}", ""));
            let _ = writeln!(s, "  {} {:<15} {detail}", item.status.label(), item.name);
        }
        let w = &self.workspace;
        let fmt_box = |b: &Aabb| {
            format!(
                "[{:.3}, {:.3}, {:.3}] … [{:.3}, {:.3}, {:.3}] m",
                b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]
            )
        };
        let _ = writeln!(s, "workspace declared: {}", fmt_box(&w.declared));
        if let Some(seen) = &w.seen {
            let _ = writeln!(s, "workspace seen:     {}", fmt_box(seen));
        }
        for t in &w.transforms {
            let _ = writeln!(
                s,
                "\nscene transform from the {} workspace onto region {} ({}; paste into the \
                 scene file):",
                t.from,
                fmt_box(&t.region),
                match t.fit {
                    Fit::Cover => "--fit cover: the whole region is reachable",
                    Fit::Inside => "--fit inside: the workspace stays inside the region",
                }
            );
            s.push_str(&t.toml);
        }
        let failed: Vec<&str> = self
            .checks
            .iter()
            .filter(|i| i.status == Status::Fail)
            .map(|i| i.name.as_str())
            .collect();
        let _ = writeln!(
            s,
            "\nresult: {}",
            if failed.is_empty() {
                "PASS".to_owned()
            } else {
                format!("FAIL ({})", failed.join(", "))
            }
        );
        s
    }
}
