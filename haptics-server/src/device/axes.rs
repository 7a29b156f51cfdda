//! Signed axis permutations: where a device's force axes really point, in the device's own
//! frame. Written like `-x,z,y`: commanded +x comes out along −x, commanded +y along +z,
//! commanded +z along +y.
//!
//! The `fake` device takes one (`--fake-axes`, `device.fake.axes`) to simulate a wiring or
//! driver error; `check --force-test` infers one from the motion it measures and describes
//! it ([`AxisMap::describe`]: "axis x inverted", "axes y and z swapped").

use std::fmt;

use glam::Vec3;

const NAMES: [char; 3] = ['x', 'y', 'z'];

/// A signed permutation of the three axes: commanded axis `i` comes out along axis
/// `target[i]` with sign `sign[i]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisMap {
    target: [usize; 3],
    negative: [bool; 3],
}

impl Default for AxisMap {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl AxisMap {
    /// Every axis where it is commanded.
    pub const IDENTITY: AxisMap = AxisMap {
        target: [0, 1, 2],
        negative: [false; 3],
    };

    /// Build from per-axis `(target, negative)`; `None` unless the targets are a permutation.
    pub fn new(axes: [(usize, bool); 3]) -> Option<Self> {
        let target = axes.map(|(t, _)| t);
        let mut seen = [false; 3];
        for &t in &target {
            if t > 2 || seen[t] {
                return None;
            }
            seen[t] = true;
        }
        Some(Self {
            target,
            negative: axes.map(|(_, n)| n),
        })
    }

    /// Parse `x,y,z`-style specs: three comma-separated axes, each optionally signed.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let parts: Vec<&str> = spec.split(',').map(str::trim).collect();
        if parts.len() != 3 {
            return Err(format!(
                "{spec:?}: expected three comma-separated axes such as \"x,y,z\" or \"-x,z,y\""
            ));
        }
        let mut axes = [(0usize, false); 3];
        for (slot, part) in axes.iter_mut().zip(&parts) {
            let (negative, name) = match part.strip_prefix('-') {
                Some(rest) => (true, rest),
                None => (false, part.strip_prefix('+').unwrap_or(part)),
            };
            let t = match name.to_ascii_lowercase().as_str() {
                "x" => 0,
                "y" => 1,
                "z" => 2,
                other => {
                    return Err(format!(
                        "{spec:?}: {other:?} is not an axis (x, y or z, optionally signed)"
                    ));
                }
            };
            *slot = (t, negative);
        }
        Self::new(axes)
            .ok_or_else(|| format!("{spec:?}: every axis must appear exactly once (x, y and z)"))
    }

    /// Where commanded axis `i` comes out: `(axis, negative)`.
    pub fn axis(&self, i: usize) -> (usize, bool) {
        (self.target[i], self.negative[i])
    }

    /// The vector as it comes out: `out[target[i]] = ±v[i]`.
    pub fn apply(&self, v: Vec3) -> Vec3 {
        let mut out = [0.0f32; 3];
        for i in 0..3 {
            let c = v[i];
            out[self.target[i]] = if self.negative[i] { -c } else { c };
        }
        Vec3::from_array(out)
    }

    /// Every axis comes out where it is commanded.
    pub fn is_identity(&self) -> bool {
        *self == Self::IDENTITY
    }

    /// What is wrong, in words: inverted axes, swapped pairs, rotated triples; empty when
    /// [`AxisMap::is_identity`].
    pub fn describe(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut done = [false; 3];
        for i in 0..3 {
            let t = self.target[i];
            if t == i {
                done[i] = true;
                if self.negative[i] {
                    out.push(format!("axis {} inverted", NAMES[i]));
                }
                continue;
            }
            if done[i] {
                continue;
            }
            if self.target[t] == i {
                done[i] = true;
                done[t] = true;
                let mut s = format!("axes {} and {} swapped", NAMES[i], NAMES[t]);
                let signs: Vec<String> = [i, t]
                    .iter()
                    .filter(|&&a| self.negative[a])
                    .map(|&a| format!("+{} comes out as -{}", NAMES[a], NAMES[self.target[a]]))
                    .collect();
                if !signs.is_empty() {
                    s.push_str(&format!(" ({})", signs.join(", ")));
                }
                out.push(s);
            }
        }
        if done.iter().any(|d| !d) {
            // A 3-cycle: name each axis's destination.
            let parts: Vec<String> = (0..3)
                .map(|i| {
                    format!(
                        "+{} → {}{}",
                        NAMES[i],
                        if self.negative[i] { '-' } else { '+' },
                        NAMES[self.target[i]]
                    )
                })
                .collect();
            out.push(format!("axes rotated: {}", parts.join(", ")));
        }
        out
    }
}

impl fmt::Display for AxisMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for i in 0..3 {
            if i > 0 {
                f.write_str(",")?;
            }
            if self.negative[i] {
                f.write_str("-")?;
            }
            write!(f, "{}", NAMES[self.target[i]])?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_apply_and_print_round_trip() {
        let m = AxisMap::parse("-x,z,y").unwrap();
        assert_eq!(m.apply(Vec3::X), -Vec3::X);
        assert_eq!(m.apply(Vec3::Y), Vec3::Z);
        assert_eq!(m.apply(Vec3::Z), Vec3::Y);
        assert_eq!(m.to_string(), "-x,z,y");
        assert_eq!(AxisMap::parse(" +X, y ,Z").unwrap(), AxisMap::IDENTITY);
        assert!(AxisMap::IDENTITY.describe().is_empty());
    }

    #[test]
    fn bad_specs_say_why() {
        assert!(AxisMap::parse("x,y").unwrap_err().contains("three"));
        assert!(
            AxisMap::parse("x,x,z")
                .unwrap_err()
                .contains("exactly once")
        );
        assert!(AxisMap::parse("x,w,z").unwrap_err().contains("\"w\""));
    }

    #[test]
    fn descriptions_name_the_axes() {
        let d = |s: &str| AxisMap::parse(s).unwrap().describe();
        assert_eq!(d("-x,y,z"), ["axis x inverted"]);
        assert_eq!(d("-x,z,y"), ["axis x inverted", "axes y and z swapped"]);
        assert_eq!(d("y,x,-z"), ["axes x and y swapped", "axis z inverted"]);
        assert_eq!(d("-y,x,z"), ["axes x and y swapped (+x comes out as -y)"]);
        assert_eq!(d("y,z,x"), ["axes rotated: +x → +y, +y → +z, +z → +x"]);
    }
}
