//! Sculpting tools (DESIGN §4): each turns a user action into forces on the dynamic model
//! ([`rope`], [`probe_sculpt`]; both are [`GridTool`]s), colours on points ([`paint`]), or point
//! displacements ([`emboss`]).
//!
//! Contract: tools are plain values (usable from a script or a device driver); applying one
//! touches only the nodes or points within its reach, allocates nothing per call beyond the
//! caller's buffers, and rejects non-finite parameters with [`ToolError`].

pub mod emboss;
pub mod paint;
pub mod probe_sculpt;
pub mod rope;

pub use probe_sculpt::{ProbeMode, ProbeSculpt};
pub use rope::{Profile, Rope};

use crate::dynamics::DynamicGrid;

/// A tool that acts on the dynamic field through node forces, once per step (after the forces
/// are cleared). [`crate::scene::Scene::step_field`] applies any mix of them.
pub trait GridTool {
    /// Add this tool's forces; returns how many nodes it touched.
    fn apply(&self, model: &mut DynamicGrid) -> Result<usize, ToolError>;
}

impl GridTool for Rope {
    fn apply(&self, model: &mut DynamicGrid) -> Result<usize, ToolError> {
        Rope::apply(self, model)
    }
}

/// Why a tool could not be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ToolError {
    /// A numeric parameter is non-finite or out of range.
    #[error("invalid tool parameter `{name}`: {reason}")]
    Param {
        /// The parameter's name (as in scripts).
        name: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// An image could not be decoded or is empty.
    #[error("image: {0}")]
    Image(String),
}

/// `Ok` if `x` is finite and positive, else a [`ToolError::Param`] naming it.
pub(crate) fn positive(name: &'static str, x: f64) -> Result<f64, ToolError> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(ToolError::Param {
            name,
            reason: "must be positive and finite",
        })
    }
}

/// `Ok` if `x` is finite, else a [`ToolError::Param`] naming it.
pub(crate) fn finite(name: &'static str, x: f64) -> Result<f64, ToolError> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(ToolError::Param {
            name,
            reason: "must be finite",
        })
    }
}
