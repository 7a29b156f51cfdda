// Shaders of the scene renderer: surface splatting in three passes (visibility, attribute,
// normalisation with deferred shading), lit meshes (opaque and translucent), wide lines.
// Colours arrive sRGB-encoded (splats) or linear (uniform/instance data); all lighting is in
// linear colour and the target is sRGB, so the hardware encodes on write.
//
// `ewa_setup` and `ewa_eval` copy `src/ewa.rs` line by line (the CPU renderer runs that file):
// change one, change the other.

struct Frame {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,       // xyz: eye position
    right: vec4<f32>,     // xyz: camera right (world), for camera-facing splats
    up: vec4<f32>,        // xyz: camera up (world)
    viewport: vec4<f32>,  // width, height, 1/width, 1/height (pixels)
    light: vec4<f32>,     // ambient, diffuse, specular, shininess
    options: vec4<f32>,   // x: 1 to cull splats whose normal faces away from the eye
    row_x: vec4<f32>,     // homogeneous pixel x·w of a world point (p, 1)
    row_y: vec4<f32>,     // homogeneous pixel y·w
    row_w: vec4<f32>,     // view depth w
    forward: vec4<f32>,   // xyz: view direction
    right_t: vec4<f32>,   // xyz: right · tan(fov/2) · aspect
    up_t: vec4<f32>,      // xyz: up · tan(fov/2)
    ewa: vec4<f32>,       // NDC depth = x + y / w; z: near; w: EPS_PX · pixel size at depth 1
    ewa_k: vec4<f32>,     // x: GAUSS_K, y: EPS_FRACTION, z: PREFILTER_PX, w: MIN_WEIGHT
};

@group(0) @binding(0) var<uniform> frame: Frame;
// The splats as uploaded (`Splat`, 64 bytes):
// [p.x, p.y, p.z, n.x], [n.y, n.z, radius, rgba8], [axis.x, axis.y, axis.z, minor_radius],
// [k_aa, k_ab, k_bb, cell_growth] (curvature, and the growth where the splat faces the eye).
@group(0) @binding(1) var<storage, read> splats: array<vec4<f32>>;
// The attribute pass's sums, read by the normalisation pass.
@group(1) @binding(0) var accum_color: texture_2d<f32>;
@group(1) @binding(1) var accum_normal: texture_2d<f32>;

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// Headlight: albedo·(ambient + diffuse·|n·l|) + specular·|n·l|^shininess (Lighting::shade).
fn shade_dir(albedo: vec3<f32>, n: vec3<f32>, l: vec3<f32>) -> vec3<f32> {
    let d = min(abs(dot(n, l)), 1.0);
    let s = frame.light.z * pow(d, frame.light.w);
    return albedo * (frame.light.x + frame.light.y * d) + vec3<f32>(s);
}

fn shade(albedo: vec3<f32>, n: vec3<f32>, world: vec3<f32>) -> vec3<f32> {
    return shade_dir(albedo, n, normalize(frame.eye.xyz - world));
}

// Triangle-strip corner of a quad: 0 (-1,-1), 1 (1,-1), 2 (-1,1), 3 (1,1).
fn corner(vi: u32) -> vec2<f32> {
    return vec2<f32>(f32(vi & 1u), f32(vi >> 1u)) * 2.0 - 1.0;
}

// ---- surface splatting ----

struct Ewa {
    center_wc: vec4<f32>, // projected centre (pixels), centre view depth, ε
    ainv: vec4<f32>,      // A⁻¹ row-major
    k: vec4<f32>,         // (uz, vz), 1 if the object-space term exists, 1 if drawn
    bbox: vec4<f32>,      // x0, y0, x1, y1 (pixels)
    cut: vec4<f32>,       // the silhouette cut: kept where 1 + xy·g − (zw·g)² ≥ 0 (zero: none)
    dn_u: vec3<f32>,      // the normal's change per unit û and v̂ (K·u, K·v; turned with it)
    dn_v: vec3<f32>,
    bend: vec3<f32>,      // S·K·t / c: the hit on the curved surface (`ewa::Silhouette`)
    quad: vec3<f32>,      // K's quadratic form in (û, v̂)
    albedo: vec3<f32>,
    normal: vec3<f32>,
};

// `ewa::CUT_SLACK`, `TURN_BELOW`, `GROW_FROM`, `GROW_FULL` and `CONTOUR_BELOW` (a test checks
// they agree).
const CUT_SLACK: f32 = 1.0;
const TURN_BELOW: f32 = 0.3;
const GROW_FROM: f32 = 0.6;
const GROW_FULL: f32 = 0.9;
const CONTOUR_BELOW: f32 = 0.5;

// `ewa::growth`: the factor on a splat's semi-axes seen at cosine `c` between its normal and
// the eye.
fn growth(cell_growth: f32, c: f32) -> f32 {
    let t = clamp((c - GROW_FROM) / (GROW_FULL - GROW_FROM), 0.0, 1.0);
    return 1.0 + (max(cell_growth, 1.0) - 1.0) * t * t * (3.0 - 2.0 * t);
}

// `ewa::Silhouette`.
struct Silhouette {
    cut: vec4<f32>,
    bend: vec3<f32>,
    quad: vec3<f32>,
};

// `ewa::silhouette`.
fn silhouette(k: vec3<f32>, n: vec3<f32>, u: vec3<f32>, v: vec3<f32>, to_eye: vec3<f32>) -> Silhouette {
    var none: Silhouette;
    none.cut = vec4<f32>(0.0);
    none.bend = vec3<f32>(0.0);
    none.quad = vec3<f32>(0.0);
    let el = length(to_eye);
    if !(el > 0.0) {
        return none;
    }
    let e = to_eye / el;
    let ne = dot(n, e);
    let t0 = e - n * ne;
    let tl = length(t0);
    let ul = length(u);
    let vl = length(v);
    if !(tl > 1e-6 && ul > 0.0 && vl > 0.0) {
        return none;
    }
    let t = t0 / tl;
    let sd = cross(n, t);
    let du = u / ul;
    let dv = v / vl;
    let tx = dot(t, du);
    let ty = dot(t, dv);
    let sx = dot(sd, du);
    let sy = dot(sd, dv);
    let kt = (k.x * tx * tx + 2.0 * k.y * tx * ty + k.z * ty * ty);
    let kts = (k.x * tx * sx + k.y * (tx * sy + ty * sx) + k.z * ty * sy);
    let ks = (k.x * sx * sx + 2.0 * k.y * sx * sy + k.z * sy * sy);
    if !(kt > 0.0) {
        return none;
    }
    let c = select(1.0, -1.0, ne < 0.0) * max(abs(ne), 1e-4);
    let sn = sqrt(max(1.0 - c * c, 0.0));
    let at = vec2<f32>(dot(u, t), dot(v, t));
    let bs = vec2<f32>(dot(u, sd), dot(v, sd));
    let l = 2.0 * sn * (kt * at + kts * bs) / (c * CUT_SLACK);
    let q = sn * sn * (kts * kts - kt * ks) / (c * c);
    var m = vec2<f32>(0.0);
    if q < 0.0 {
        m = bs * (sqrt(-q) / CUT_SLACK);
    }
    var out = none;
    out.cut = vec4<f32>(l, m);
    if ne <= 0.0 {
        return out;
    }
    let kt_world = (k.x * tx + k.y * ty) * du + (k.y * tx + k.z * ty) * dv;
    out.bend = kt_world * (sn / c);
    out.quad = vec3<f32>(k.x * ul * ul, k.y * ul * vl, k.z * vl * vl);
    return out;
}

// `ewa::hit_normal`: the curved surface's normal where the eye's ray meets it, at the plane
// point uv (zero from the pre-filter).
fn hit_normal(normal: vec3<f32>, dn_u: vec3<f32>, dn_v: vec3<f32>, cut: vec4<f32>, bend: vec3<f32>, quad: vec3<f32>, uv: vec2<f32>) -> vec3<f32> {
    let plane = normal + uv.x * dn_u + uv.y * dn_v;
    let q = quad.x * uv.x * uv.x + 2.0 * quad.y * uv.x * uv.y + quad.z * uv.y * uv.y;
    if q == 0.0 {
        return plane;
    }
    let lg = CUT_SLACK * (cut.x * uv.x + cut.y * uv.y);
    let mg = CUT_SLACK * (cut.z * uv.x + cut.w * uv.y);
    let sigma = q / (1.0 + 0.5 * lg + sqrt(max(1.0 + lg - mg * mg, 0.0)));
    let b = sigma * bend;
    let len = length(b);
    // `len == len` is false for NaN; 3.4e38 stands for infinity.
    if !(len == len && len < 3.4e38 && sigma > 0.0) {
        return plane;
    }
    if len > 1.0 {
        return plane - b / len;
    }
    return plane - b;
}

// `ewa::setup`: the splat's projected ellipse; k.w = 0 when it draws nothing.
fn ewa_setup(i: u32) -> Ewa {
    var e: Ewa;
    e.k = vec4<f32>(0.0);
    let a4 = splats[4u * i];
    let b4 = splats[4u * i + 1u];
    let c4 = splats[4u * i + 2u];
    let d4 = splats[4u * i + 3u];
    let p = a4.xyz;
    let raw_n = vec3<f32>(a4.w, b4.xy);
    let to_eye = frame.eye.xyz - p;
    let len2 = dot(raw_n, raw_n);
    var n: vec3<f32>;
    var t1: vec3<f32>;
    var t2: vec3<f32>;
    if len2 > 1e-12 {
        n = raw_n / sqrt(len2);
        // Orthonormal tangent basis without branches on the axis (Duff et al. 2017).
        let sgn = select(-1.0, 1.0, n.z >= 0.0);
        let a = -1.0 / (sgn + n.z);
        let b = n.x * n.y * a;
        t1 = vec3<f32>(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x);
        t2 = vec3<f32>(b, sgn + n.y * n.y * a, -n.y);
    } else {
        n = normalize(to_eye);
        t1 = frame.right.xyz;
        t2 = frame.up.xyz;
    }
    let facing = dot(n, to_eye);
    if frame.options.x > 0.5 && len2 > 1e-12 && facing < 0.0 {
        return e;
    }
    let turned = facing < -TURN_BELOW * length(to_eye);
    let grow = growth(d4.w, abs(facing) / max(length(to_eye), 1e-30));
    let ra = b4.z * grow;
    let axis = c4.xyz;
    let ax = axis - n * dot(axis, n);
    let ax2 = dot(ax, ax);
    var du = t1;
    var dv = t2;
    var rb = ra;
    if ax2 > 1e-12 {
        du = ax / sqrt(ax2);
        dv = cross(n, du);
        rb = c4.w * grow;
    }
    if !(ra > 0.0 && rb > 0.0) {
        return e;
    }
    let u = du * ra;
    let v = dv * rb;
    e.cut = vec4<f32>(0.0);
    e.dn_u = vec3<f32>(0.0);
    e.dn_v = vec3<f32>(0.0);
    e.bend = vec3<f32>(0.0);
    e.quad = vec3<f32>(0.0);
    if ax2 > 1e-12 {
        let sil = silhouette(d4.xyz, n, u, v, to_eye);
        e.cut = sil.cut;
        e.bend = sil.bend;
        e.quad = sil.quad;
        let turn = select(1.0, -1.0, turned);
        e.dn_u = turn * ra * (d4.x * du + d4.y * dv);
        e.dn_v = turn * rb * (d4.y * du + d4.z * dv);
    }
    let pc = vec4<f32>(p, 1.0);
    let wc = dot(frame.row_w, pc);
    let cx = dot(frame.row_x, pc) / wc;
    let cy = dot(frame.row_y, pc) / wc;
    let hu = vec3<f32>(dot(frame.row_x.xyz, u), dot(frame.row_y.xyz, u), dot(frame.row_w.xyz, u));
    let hv = vec3<f32>(dot(frame.row_x.xyz, v), dot(frame.row_y.xyz, v), dot(frame.row_w.xyz, v));
    let ux = hu.x - cx * hu.z;
    let uy = hu.y - cy * hu.z;
    let uz = hu.z;
    let vx = hv.x - cx * hv.z;
    let vy = hv.y - cy * hv.z;
    let vz = hv.z;
    if wc - sqrt(uz * uz + vz * vz) < 0.5 * frame.ewa.z {
        return e;
    }
    let qa = wc * wc - uz * uz - vz * vz;
    let qbx = -(ux * uz + vx * vz);
    let qcx = -(ux * ux + vx * vx);
    let rx = sqrt(max(qbx * qbx - qa * qcx, 0.0));
    let qby = -(uy * uz + vy * vz);
    let qcy = -(uy * uy + vy * vy);
    let ry = sqrt(max(qby * qby - qa * qcy, 0.0));
    let pf = frame.ewa_k.z;
    e.bbox = vec4<f32>(
        cx + min((qbx - rx) / qa, -pf),
        cy + min((qby - ry) / qa, -pf),
        cx + max((qbx + rx) / qa, pf),
        cy + max((qby + ry) / qa, pf),
    );
    let det = ux * vy - vx * uy;
    let obj = abs(det) > 1e-4 * sqrt(ux * ux + uy * uy) * sqrt(vx * vx + vy * vy);
    e.ainv = vec4<f32>(0.0);
    if obj {
        e.ainv = vec4<f32>(vy, -vx, -uy, ux) / det;
    }
    e.center_wc = vec4<f32>(cx, cy, wc, frame.ewa_k.y * ra + frame.ewa.w * wc);
    e.k = vec4<f32>(uz, vz, select(0.0, 1.0, obj), 1.0);
    e.albedo = srgb_to_linear(unpack4x8unorm(bitcast<u32>(b4.w)).rgb);
    e.normal = select(n, -n, turned);
    return e;
}

// `ewa::eval` at pixel centre `pos`: v = (weight, depth, pushed depth, 1), or v.w = 0 outside;
// uv = (û, v̂) of the object-space hit (zero from the screen-space pre-filter); graze = 1 where
// the pre-filter covers a point the silhouette cut removes.
struct EwaSample {
    v: vec4<f32>,
    uv: vec2<f32>,
    graze: f32,
};

fn ewa_eval(center_wc: vec4<f32>, ainv: vec4<f32>, k: vec4<f32>, bbox: vec4<f32>, cut: vec4<f32>, pos: vec2<f32>) -> EwaSample {
    var none: EwaSample;
    if pos.x < bbox.x || pos.x > bbox.z || pos.y < bbox.y || pos.y > bbox.w {
        return none;
    }
    let dx = pos.x - center_wc.x;
    let dy = pos.y - center_wc.y;
    let gx = ainv.x * dx + ainv.y * dy;
    let gy = ainv.z * dx + ainv.w * dy;
    let den = 1.0 - (k.x * gx + k.y * gy);
    let pf = frame.ewa_k.z;
    let d2_scr = (dx * dx + dy * dy) * (1.0 / (pf * pf));
    var d2 = d2_scr;
    var w = center_wc.z;
    var uv = vec2<f32>(0.0);
    var graze = 0.0;
    if k.z > 0.5 && den > 1e-6 {
        let scale = center_wc.z / den;
        let d2_obj = (gx * gx + gy * gy) * (scale * scale);
        let cu = gx * scale;
        let cv = gy * scale;
        let across = cut.z * cu + cut.w * cv;
        let kept = 1.0 + cut.x * cu + cut.y * cv - across * across >= 0.0;
        if kept && d2_obj <= d2_scr {
            d2 = d2_obj;
            w = scale;
            uv = vec2<f32>(cu, cv);
        } else if !kept {
            graze = 1.0;
        }
    }
    if d2 > 1.0 {
        return none;
    }
    let depth = frame.ewa.x + frame.ewa.y / w;
    if !(depth >= 0.0 && depth <= 1.0) {
        return none;
    }
    let pushed = min(frame.ewa.x + frame.ewa.y / (w + center_wc.w), 1.0);
    let edge = exp(-frame.ewa_k.x);
    var out: EwaSample;
    out.v = vec4<f32>((exp(-frame.ewa_k.x * d2) - edge) * (1.0 / (1.0 - edge)), depth, pushed, 1.0);
    out.uv = uv;
    out.graze = graze;
    return out;
}

// `ewa::graze_normal`: the normal turned perpendicular to the eye direction `e`.
fn graze_normal(n: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    let g = n - dot(n, e) * e;
    if dot(g, g) > 0.0 {
        return normalize(g);
    }
    return n;
}

// `FrameParams::eye_dir` at pixel centre `pos`.
fn eye_dir(pos: vec2<f32>) -> vec3<f32> {
    let nx = pos.x * 2.0 * frame.viewport.z - 1.0;
    let ny = 1.0 - pos.y * 2.0 * frame.viewport.w;
    return -normalize(frame.forward.xyz + nx * frame.right_t.xyz + ny * frame.up_t.xyz);
}

struct EwaOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) center_wc: vec4<f32>,
    @location(1) @interpolate(flat) ainv: vec4<f32>,
    @location(2) @interpolate(flat) k: vec4<f32>,
    @location(3) @interpolate(flat) bbox: vec4<f32>,
    @location(4) @interpolate(flat) albedo: vec3<f32>,
    @location(5) @interpolate(flat) normal: vec3<f32>,
    @location(6) @interpolate(flat) cut: vec4<f32>,
    @location(7) @interpolate(flat) dn_u: vec3<f32>,
    @location(8) @interpolate(flat) dn_v: vec3<f32>,
    @location(9) @interpolate(flat) bend: vec3<f32>,
    @location(10) @interpolate(flat) quad: vec3<f32>,
};

// Splat vi / 6, corner vi % 6 of the two triangles covering its pixel box exactly: half the
// fragments of one triangle enclosing the box, which costs more than the extra triangle.
@vertex
fn vs_ewa(@builtin(vertex_index) vi: u32) -> EwaOut {
    let e = ewa_setup(vi / 6u);
    var out: EwaOut;
    out.center_wc = e.center_wc;
    out.ainv = e.ainv;
    out.k = e.k;
    out.bbox = e.bbox;
    out.albedo = e.albedo;
    out.normal = e.normal;
    out.cut = e.cut;
    out.dn_u = e.dn_u;
    out.dn_v = e.dn_v;
    out.bend = e.bend;
    out.quad = e.quad;
    if e.k.w < 0.5 {
        out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0); // draws nothing: one point outside the view
        return out;
    }
    let lo = clamp(e.bbox.xy, vec2<f32>(-1.0), frame.viewport.xy + 1.0);
    let hi = clamp(e.bbox.zw, vec2<f32>(-1.0), frame.viewport.xy + 1.0);
    // Corners 0 1 2, 2 1 3 of the box (bit 0: x high, bit 1: y high).
    var quad = array<u32, 6>(0u, 1u, 2u, 2u, 1u, 3u);
    let c = quad[vi % 6u];
    let px = select(lo, hi, vec2<bool>((c & 1u) != 0u, (c & 2u) != 0u));
    out.clip = vec4<f32>(px.x * 2.0 * frame.viewport.z - 1.0, 1.0 - px.y * 2.0 * frame.viewport.w, 0.5, 1.0);
    return out;
}

// Pass 1, visibility: the nearest depth pushed back by ε.
@fragment
fn fs_ewa_visibility(v: EwaOut) -> @builtin(frag_depth) f32 {
    let s = ewa_eval(v.center_wc, v.ainv, v.k, v.bbox, v.cut, v.clip.xy).v;
    if s.w < 0.5 {
        discard;
    }
    return s.z;
}

struct AttributeOut {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @builtin(frag_depth) depth: f32,
};

// Pass 2, attributes: every fragment within ε of the front adds w·albedo, w, w·normal (the
// curved surface's normal where the eye's ray meets it, `hit_normal`).
@fragment
fn fs_ewa_attribute(v: EwaOut) -> AttributeOut {
    let r = ewa_eval(v.center_wc, v.ainv, v.k, v.bbox, v.cut, v.clip.xy);
    let s = r.v;
    if s.w < 0.5 {
        discard;
    }
    var out: AttributeOut;
    out.color = vec4<f32>(s.x * v.albedo, s.x);
    var n = hit_normal(v.normal, v.dn_u, v.dn_v, v.cut, v.bend, v.quad, r.uv);
    if r.graze > 0.5 {
        n = graze_normal(v.normal, eye_dir(v.clip.xy));
    }
    out.normal = vec4<f32>(s.x * n, 0.0);
    out.depth = s.y;
    return out;
}

@vertex
fn vs_fullscreen(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// Whether nothing weighs at pixel `ip` (outside the target: no).
fn empty_at(ip: vec2<i32>) -> bool {
    let dims = vec2<i32>(textureDimensions(accum_color));
    if ip.x < 0 || ip.y < 0 || ip.x >= dims.x || ip.y >= dims.y {
        return false;
    }
    return textureLoad(accum_color, ip, 0).w < frame.ewa_k.w;
}

// Pass 3, normalisation: Σw·albedo / Σw, shaded with the normalised Σw·normal; the background
// (the clear colour) where nothing weighs.
@fragment
fn fs_ewa_normalise(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let ip = vec2<i32>(pos.xy);
    let c = textureLoad(accum_color, ip, 0);
    if c.w < frame.ewa_k.w {
        discard;
    }
    let l = eye_dir(pos.xy);
    let sum_n = textureLoad(accum_normal, ip, 0).xyz;
    var n = l;
    if dot(sum_n, sum_n) > 0.0 {
        n = normalize(sum_n);
    }
    // Next to the background and near grazing: an outline, where the surface's normal is
    // perpendicular to the eye.
    let outline = empty_at(ip + vec2<i32>(-1, 0)) || empty_at(ip + vec2<i32>(1, 0))
        || empty_at(ip + vec2<i32>(0, -1)) || empty_at(ip + vec2<i32>(0, 1));
    if outline && abs(dot(n, l)) < CONTOUR_BELOW {
        n = graze_normal(n, l);
    }
    return vec4<f32>(shade_dir(c.rgb / c.w, n, l), 1.0);
}

// ---- lit meshes (cursor, arrow head, probe) ----

struct MeshIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) m0: vec4<f32>,
    @location(3) m1: vec4<f32>,
    @location(4) m2: vec4<f32>,
    @location(5) m3: vec4<f32>,
    @location(6) n0: vec4<f32>,
    @location(7) n1: vec4<f32>,
    @location(8) n2: vec4<f32>,
    @location(9) color: vec4<f32>,
};

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) @interpolate(flat) color: vec4<f32>,
};

@vertex
fn vs_mesh(m: MeshIn) -> MeshOut {
    let model = mat4x4<f32>(m.m0, m.m1, m.m2, m.m3);
    let normal_mat = mat3x3<f32>(m.n0.xyz, m.n1.xyz, m.n2.xyz);
    let world = (model * vec4<f32>(m.position, 1.0)).xyz;
    var out: MeshOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.normal = normal_mat * m.normal;
    out.color = m.color;
    return out;
}

@fragment
fn fs_mesh_opaque(v: MeshOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(v.color.rgb, normalize(v.normal), v.world), 1.0);
}

// Translucent: the instance alpha at the centre, rising towards the silhouette so the outline
// of the probe reads against the surface behind it.
@fragment
fn fs_mesh_translucent(v: MeshOut) -> @location(0) vec4<f32> {
    let n = normalize(v.normal);
    let facing = abs(dot(n, normalize(frame.eye.xyz - v.world)));
    let rim = pow(1.0 - facing, 3.0);
    let alpha = v.color.a + (1.0 - v.color.a) * 0.6 * rim;
    return vec4<f32>(shade(v.color.rgb, n, v.world), alpha);
}

// ---- wide lines ----

struct LineIn {
    @location(0) a: vec4<f32>,   // xyz: start, w: width in pixels
    @location(1) b: vec4<f32>,   // xyz: end
    @location(2) color: vec4<f32>,
};

struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) color: vec4<f32>,
};

// Clips the segment to the near plane (clip z >= 0), then widens it in screen space into a quad
// `width` pixels across, extended by half the width at both ends so corners meet.
@vertex
fn vs_line(@builtin(vertex_index) vi: u32, l: LineIn) -> LineOut {
    var ca = frame.view_proj * vec4<f32>(l.a.xyz, 1.0);
    var cb = frame.view_proj * vec4<f32>(l.b.xyz, 1.0);
    var out: LineOut;
    out.color = l.color;
    if ca.z < 0.0 && cb.z < 0.0 {
        out.clip = vec4<f32>(0.0, 0.0, -1.0, 1.0); // wholly behind the near plane: culled
        return out;
    }
    if ca.z < 0.0 {
        ca = mix(ca, cb, ca.z / (ca.z - cb.z));
    } else if cb.z < 0.0 {
        cb = mix(cb, ca, cb.z / (cb.z - ca.z));
    }
    let half_px = 0.5 * frame.viewport.xy;
    let sa = ca.xy / ca.w * half_px;
    let sb = cb.xy / cb.w * half_px;
    var dir = sb - sa;
    let len = length(dir);
    dir = select(vec2<f32>(1.0, 0.0), dir / len, len > 1e-6);
    let perp = vec2<f32>(-dir.y, dir.x);
    let c = corner(vi);
    let end = select(ca, cb, c.x > 0.0);
    let offset_px = 0.5 * l.a.w * (perp * c.y + dir * c.x);
    out.clip = end + vec4<f32>(offset_px / half_px * end.w, 0.0, 0.0);
    return out;
}

@fragment
fn fs_line(v: LineOut) -> @location(0) vec4<f32> {
    return v.color;
}
