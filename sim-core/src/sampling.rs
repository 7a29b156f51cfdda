//! Analytic shapes with exact signed distances (negative inside), for ground truth, and seeded
//! samplers drawing points uniformly by area with their exact outward normals, optionally noisy.
//!
//! Contract: deterministic for a given seed; every sample is finite with a unit normal.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::pointset::PointSet;

/// An analytic closed surface centred at the origin.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Shape {
    /// Sphere of the given radius.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// Axis-aligned ellipsoid with semi-axes `radii`.
    Ellipsoid {
        /// Semi-axes along x, y, z.
        radii: DVec3,
    },
    /// Torus around the z axis.
    Torus {
        /// Distance from the centre to the tube's centre line.
        major: f64,
        /// Tube radius (< `major`).
        minor: f64,
    },
    /// Axis-aligned box with half extents `half`, edges and corners rounded by `radius`.
    RoundedBox {
        /// Half extents (each ≥ `radius`).
        half: DVec3,
        /// Rounding radius.
        radius: f64,
    },
    /// Closed cylinder around the z axis.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Half of the height.
        half_height: f64,
    },
    /// Square plate in the xy plane: a rounded box `half × half × thickness/2` whose edges are
    /// half cylinders. A thin plate is a thin shell: two sheets `thickness` apart.
    Plate {
        /// Half of the side length.
        half_size: f64,
        /// Thickness.
        thickness: f64,
    },
    /// A CSG difference with a sharp crease: the sphere of `radius` at the origin minus the
    /// sphere of radius `cutter` centred at `(offset, 0, 0)` (which must cut its rim:
    /// `|radius − cutter| < offset < radius + cutter`, and `offset > 0`).
    Carved {
        /// The body's radius.
        radius: f64,
        /// The cutter's radius.
        cutter: f64,
        /// The cutter's centre on +x.
        offset: f64,
    },
}

/// Perturbations for noisy samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Noise {
    /// Standard deviation of the displacement along the normal, in metres.
    pub position: f64,
    /// Standard deviation of the normal's tilt, in radians (approximately).
    pub normal: f64,
}

impl Shape {
    /// Exact signed distance (negative inside).
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        match *self {
            Shape::Sphere { radius } => p.length() - radius,
            Shape::Ellipsoid { radii } => ellipsoid_distance(radii, p),
            Shape::Torus { major, minor } => {
                DVec3::new(p.truncate().length() - major, p.z, 0.0).length() - minor
            }
            Shape::RoundedBox { half, radius } => {
                let q = p.abs() - (half - DVec3::splat(radius));
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0) - radius
            }
            Shape::Cylinder {
                radius,
                half_height,
            } => {
                let d = glam::DVec2::new(p.truncate().length() - radius, p.z.abs() - half_height);
                d.max_element().min(0.0) + d.max(glam::DVec2::ZERO).length()
            }
            Shape::Plate { .. } => self.as_box().signed_distance(p),
            Shape::Carved {
                radius,
                cutter,
                offset,
            } => {
                let c = DVec3::new(offset, 0.0, 0.0);
                let inside = p.length() < radius && (p - c).length() > cutter;
                let d = carved_distance(radius, cutter, offset, p);
                if inside { -d } else { d }
            }
        }
    }

    /// A length for relative errors: the radius of a sphere, the bounding-box diagonal otherwise.
    pub fn reference_size(&self) -> f64 {
        match *self {
            Shape::Sphere { radius } => radius,
            _ => {
                let (lo, hi) = self.bounds();
                (hi - lo).length()
            }
        }
    }

    /// Axis-aligned bounding box.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let h = match *self {
            Shape::Sphere { radius } => DVec3::splat(radius),
            Shape::Ellipsoid { radii } => radii,
            Shape::Torus { major, minor } => DVec3::new(major + minor, major + minor, minor),
            Shape::RoundedBox { half, .. } => half,
            Shape::Cylinder {
                radius,
                half_height,
            } => DVec3::new(radius, radius, half_height),
            Shape::Plate {
                half_size,
                thickness,
            } => DVec3::new(half_size, half_size, thickness / 2.0),
            Shape::Carved { radius, .. } => DVec3::splat(radius),
        };
        (-h, h)
    }

    /// Surface area (exact, except the ellipsoid's, which uses Thomsen's approximation).
    pub fn area(&self) -> f64 {
        match *self {
            Shape::Sphere { radius } => 4.0 * PI * radius * radius,
            Shape::Ellipsoid { radii: r } => {
                let p = 1.6075;
                let m = ((r.x * r.y).powf(p) + (r.x * r.z).powf(p) + (r.y * r.z).powf(p)) / 3.0;
                4.0 * PI * m.powf(1.0 / p)
            }
            Shape::Torus { major, minor } => 4.0 * PI * PI * major * minor,
            Shape::RoundedBox { half, radius } => {
                let e = half - DVec3::splat(radius);
                8.0 * (e.x * e.y + e.y * e.z + e.x * e.z)
                    + 2.0 * PI * radius * (e.x + e.y + e.z)
                    + 4.0 * PI * radius * radius
            }
            Shape::Cylinder {
                radius,
                half_height,
            } => TAU * radius * 2.0 * half_height + 2.0 * PI * radius * radius,
            Shape::Plate { .. } => self.as_box().area(),
            Shape::Carved {
                radius: r,
                cutter: q,
                offset: d,
            } => {
                // Spherical caps cut by the plane of the crease circle, x = a.
                let a = (r * r - q * q + d * d) / (2.0 * d);
                TAU * r * (r + a) + TAU * q * (q - (d - a))
            }
        }
    }

    /// `n` points uniformly distributed by area, with exact normals (seeded).
    pub fn sample(&self, n: usize, seed: u64) -> PointSet {
        self.sample_noisy(n, seed, Noise::default())
    }

    /// `n` points uniformly by area, displaced along the normal and with tilted normals.
    pub fn sample_noisy(&self, n: usize, seed: u64, noise: Noise) -> PointSet {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut positions = Vec::with_capacity(n);
        let mut normals = Vec::with_capacity(n);
        for _ in 0..n {
            let (p, nrm) = self.sample_one(&mut rng);
            let p = p + nrm * (noise.position * gaussian(&mut rng));
            let tilt = DVec3::new(gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng));
            let tilted = (nrm + tilt * noise.normal).try_normalize().unwrap_or(nrm);
            positions.push(p);
            normals.push(if noise.normal > 0.0 { tilted } else { nrm });
        }
        PointSet {
            positions,
            normals: Some(normals),
            colors: None,
        }
    }

    fn as_box(&self) -> Shape {
        match *self {
            Shape::Plate {
                half_size,
                thickness,
            } => Shape::RoundedBox {
                half: DVec3::new(half_size, half_size, thickness / 2.0),
                radius: thickness / 2.0,
            },
            other => other,
        }
    }

    fn sample_one(&self, rng: &mut ChaCha8Rng) -> (DVec3, DVec3) {
        match *self {
            Shape::Sphere { radius } => {
                let n = unit_vector(rng);
                (n * radius, n)
            }
            Shape::Ellipsoid { radii: r } => {
                let gmax = (r.y * r.z).max(r.x * r.z).max(r.x * r.y);
                loop {
                    let u = unit_vector(rng);
                    let g = DVec3::new(r.y * r.z * u.x, r.x * r.z * u.y, r.x * r.y * u.z).length();
                    if rng.random::<f64>() * gmax <= g {
                        let p = r * u;
                        return (p, (p / (r * r)).normalize());
                    }
                }
            }
            Shape::Torus { major, minor } => loop {
                let (theta, phi) = (rng.random::<f64>() * TAU, rng.random::<f64>() * TAU);
                if rng.random::<f64>() * (major + minor) <= major + minor * phi.cos() {
                    let n = DVec3::new(phi.cos() * theta.cos(), phi.cos() * theta.sin(), phi.sin());
                    let c = DVec3::new(major * theta.cos(), major * theta.sin(), 0.0);
                    return (c + n * minor, n);
                }
            },
            Shape::RoundedBox { half, radius } => sample_rounded_box(rng, half, radius),
            Shape::Cylinder {
                radius,
                half_height,
            } => {
                let side = TAU * radius * 2.0 * half_height;
                let theta = rng.random::<f64>() * TAU;
                let (c, s) = (theta.cos(), theta.sin());
                if rng.random::<f64>() * self.area() < side {
                    let z = (rng.random::<f64>() * 2.0 - 1.0) * half_height;
                    (DVec3::new(radius * c, radius * s, z), DVec3::new(c, s, 0.0))
                } else {
                    let r = radius * rng.random::<f64>().sqrt();
                    let top = rng.random::<bool>();
                    let z = if top { half_height } else { -half_height };
                    (
                        DVec3::new(r * c, r * s, z),
                        DVec3::new(0.0, 0.0, z.signum()),
                    )
                }
            }
            Shape::Plate { .. } => self.as_box().sample_one(rng),
            Shape::Carved {
                radius,
                cutter,
                offset,
            } => loop {
                // Area-uniform on both spheres, kept where they bound the difference.
                let c = DVec3::new(offset, 0.0, 0.0);
                let u = unit_vector(rng);
                let body =
                    rng.random::<f64>() * (radius * radius + cutter * cutter) < radius * radius;
                if body {
                    let p = u * radius;
                    if (p - c).length() >= cutter {
                        return (p, u);
                    }
                } else {
                    let p = c + u * cutter;
                    if p.length() <= radius {
                        return (p, -u);
                    }
                }
            },
        }
    }
}

/// Exact distance to the surface of [`Shape::Carved`]: the nearer of its two spherical patches,
/// each the radial projection when that lands on the patch, else the crease circle.
fn carved_distance(radius: f64, cutter: f64, offset: f64, p: DVec3) -> f64 {
    let c = DVec3::new(offset, 0.0, 0.0);
    let a = (radius * radius - cutter * cutter + offset * offset) / (2.0 * offset);
    let rho = (radius * radius - a * a).max(0.0).sqrt();
    let to_crease = glam::DVec2::new(p.x - a, glam::DVec2::new(p.y, p.z).length() - rho).length();
    let on_body = p.try_normalize().map(|u| u * radius);
    let body = match on_body {
        Some(q) if (q - c).length() >= cutter => (p.length() - radius).abs(),
        _ => to_crease,
    };
    let on_cutter = (p - c).try_normalize().map(|u| c + u * cutter);
    let cut = match on_cutter {
        Some(q) if q.length() <= radius => ((p - c).length() - cutter).abs(),
        _ => to_crease,
    };
    body.min(cut)
}

fn sample_rounded_box(rng: &mut ChaCha8Rng, half: DVec3, r: f64) -> (DVec3, DVec3) {
    let e = (half - DVec3::splat(r)).max(DVec3::ZERO);
    let faces = 8.0 * (e.x * e.y + e.y * e.z + e.x * e.z);
    let edges = 2.0 * PI * r * (e.x + e.y + e.z);
    let pick = rng.random::<f64>() * (faces + edges + 4.0 * PI * r * r);
    let sign = |rng: &mut ChaCha8Rng| if rng.random::<bool>() { 1.0 } else { -1.0 };
    let unif = |rng: &mut ChaCha8Rng, h: f64| (rng.random::<f64>() * 2.0 - 1.0) * h;
    if pick < faces {
        // Face normal to axis a, chosen by area.
        let areas = [e.y * e.z, e.x * e.z, e.x * e.y];
        let mut t = rng.random::<f64>() * (areas[0] + areas[1] + areas[2]);
        let mut a = 0;
        while a < 2 && t >= areas[a] {
            t -= areas[a];
            a += 1;
        }
        let s = sign(rng);
        let mut p = DVec3::new(unif(rng, e.x), unif(rng, e.y), unif(rng, e.z));
        p[a] = s * (e[a] + r);
        let mut n = DVec3::ZERO;
        n[a] = s;
        (p, n)
    } else if pick < faces + edges {
        // Edge along axis a, chosen by length.
        let mut t = rng.random::<f64>() * (e.x + e.y + e.z);
        let mut a = 0;
        while a < 2 && t >= e[a] {
            t -= e[a];
            a += 1;
        }
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let alpha = rng.random::<f64>() * FRAC_PI_2;
        let (sb, sc) = (sign(rng), sign(rng));
        let mut n = DVec3::ZERO;
        n[b] = sb * alpha.cos();
        n[c] = sc * alpha.sin();
        let mut p = n * r;
        p[a] = unif(rng, e[a]);
        p[b] += sb * e[b];
        p[c] += sc * e[c];
        (p, n)
    } else {
        let n = unit_vector(rng);
        (e * n.signum() + n * r, n)
    }
}

/// Exact distance to an axis-aligned ellipsoid by bisection on the Lagrange parameter (Eberly),
/// signed negative inside. Coordinates on a symmetry plane are nudged by 1e-12 of the axis, which
/// only matters near the medial sheet deep inside.
fn ellipsoid_distance(r: DVec3, p: DVec3) -> f64 {
    let y = p.abs().max(r * 1e-12);
    let f = |t: f64| {
        let q = r * y / (DVec3::splat(t) + r * r);
        q.length_squared() - 1.0
    };
    let inside = (y / r).length_squared() < 1.0;
    let rmin2 = r.min_element().powi(2);
    let (mut lo, mut hi) = if inside {
        (-rmin2, 0.0)
    } else {
        (0.0, r.max_element() * y.length())
    };
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid == lo || mid == hi {
            break;
        }
        if f(mid) > 0.0 { lo = mid } else { hi = mid }
    }
    let t = 0.5 * (lo + hi);
    let closest = r * r * y / (DVec3::splat(t) + r * r);
    let d = (y - closest).length();
    if inside { -d } else { d }
}

/// A uniformly distributed unit vector.
pub fn unit_vector(rng: &mut impl Rng) -> DVec3 {
    loop {
        let v = DVec3::new(gaussian(rng), gaussian(rng), gaussian(rng));
        if let Some(n) = v.try_normalize() {
            return n;
        }
    }
}

/// A standard normal deviate (Box–Muller).
pub fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1 = 1.0 - rng.random::<f64>();
    let u2 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}
