// Shaders of the scene renderer: surfel splats, lit meshes (opaque and translucent), wide lines.
// Colours arrive sRGB-encoded (splats) or linear (uniform/instance data); all lighting is in
// linear colour and the target is sRGB, so the hardware encodes on write.

struct Frame {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,       // xyz: eye position
    right: vec4<f32>,     // xyz: camera right (world), for camera-facing splats
    up: vec4<f32>,        // xyz: camera up (world)
    viewport: vec4<f32>,  // width, height, 1/width, 1/height (pixels)
    light: vec4<f32>,     // ambient, diffuse, specular, shininess
    options: vec4<f32>,   // x: 1 to cull splats whose normal faces away from the eye
};

@group(0) @binding(0) var<uniform> frame: Frame;
// The splats as uploaded (`Splat`, 32 bytes): [p.x, p.y, p.z, n.x], [n.y, n.z, radius, rgba8].
@group(0) @binding(1) var<storage, read> splats: array<vec4<f32>>;

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// Headlight: albedo·(ambient + diffuse·|n·l|) + specular·|n·l|^shininess (Lighting::shade).
fn shade(albedo: vec3<f32>, n: vec3<f32>, world: vec3<f32>) -> vec3<f32> {
    let l = normalize(frame.eye.xyz - world);
    let d = min(abs(dot(n, l)), 1.0);
    let s = frame.light.z * pow(d, frame.light.w);
    return albedo * (frame.light.x + frame.light.y * d) + vec3<f32>(s);
}

// Triangle-strip corner of a quad: 0 (-1,-1), 1 (1,-1), 2 (-1,1), 3 (1,1).
fn corner(vi: u32) -> vec2<f32> {
    return vec2<f32>(f32(vi & 1u), f32(vi >> 1u)) * 2.0 - 1.0;
}

// ---- surfel splats ----

struct SplatOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) world: vec3<f32>,
    @location(2) @interpolate(flat) normal: vec3<f32>,
    @location(3) @interpolate(flat) albedo: vec3<f32>,
};

// Splat vi / 3, corner vi % 3 of the one triangle that encloses its disk.
@vertex
fn vs_splat(@builtin(vertex_index) vi: u32) -> SplatOut {
    let a = splats[2u * (vi / 3u)];
    let b = splats[2u * (vi / 3u) + 1u];
    let position = a.xyz;
    let normal = vec3<f32>(a.w, b.xy);
    let radius = b.z;
    // The equilateral triangle whose incircle is the unit disk: corners at radius 2.
    var corners = array<vec2<f32>, 3>(
        vec2<f32>(0.0, 2.0), vec2<f32>(-1.7320508, -1.0), vec2<f32>(1.7320508, -1.0)
    );
    let uv = corners[vi % 3u];
    var n: vec3<f32>;
    var t1: vec3<f32>;
    var t2: vec3<f32>;
    let len2 = dot(normal, normal);
    if len2 > 1e-12 {
        n = normal * inverseSqrt(len2);
        // Orthonormal tangent basis without branches on the axis (Duff et al. 2017).
        let sgn = select(-1.0, 1.0, n.z >= 0.0);
        let a = -1.0 / (sgn + n.z);
        let b = n.x * n.y * a;
        t1 = vec3<f32>(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x);
        t2 = vec3<f32>(b, sgn + n.y * n.y * a, -n.y);
    } else {
        n = normalize(frame.eye.xyz - position);
        t1 = frame.right.xyz;
        t2 = frame.up.xyz;
    }
    let world = position + radius * (uv.x * t1 + uv.y * t2);
    var out: SplatOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    if frame.options.x > 0.5 && len2 > 1e-12 && dot(n, frame.eye.xyz - position) < 0.0 {
        out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0); // back-facing: one point outside the view
    }
    out.uv = uv;
    out.world = world;
    out.normal = n;
    out.albedo = srgb_to_linear(unpack4x8unorm(bitcast<u32>(b.w)).rgb);
    return out;
}

@fragment
fn fs_splat(v: SplatOut) -> @location(0) vec4<f32> {
    if dot(v.uv, v.uv) > 1.0 {
        discard;
    }
    return vec4<f32>(shade(v.albedo, v.normal, v.world), 1.0);
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
