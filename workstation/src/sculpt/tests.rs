//! Script parsing (every example, and bad scripts naming their field) and a small end-to-end run.

use super::run_script;
use super::script::Script;

const EXAMPLES: [(&str, &str); 5] = [
    ("bump", include_str!("../../../examples/sculpt/bump.toml")),
    ("drag", include_str!("../../../examples/sculpt/drag.toml")),
    ("carve", include_str!("../../../examples/sculpt/carve.toml")),
    (
        "emboss",
        include_str!("../../../examples/sculpt/emboss.toml"),
    ),
    ("shell", include_str!("../../../examples/sculpt/shell.toml")),
];

#[test]
fn every_example_parses() {
    for (name, text) in EXAMPLES {
        if let Err(e) = Script::parse(text) {
            panic!("{name}: {e}");
        }
    }
}

const BASE: &str = r#"
[[object]]
name = "ball"
generate = { shape = "sphere", size = 0.05, points = 800, seed = 1 }

[region]
object = "ball"
min = [-0.03, -0.03, 0.02]
max = [0.03, 0.03, 0.07]
spacing = 0.004
band = 0.01
"#;

fn error_of(extra: &str) -> String {
    match Script::parse(&format!("{BASE}{extra}")) {
        Ok(_) => panic!("accepted:\n{extra}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_scripts_name_the_field_and_reason() {
    let cases = [
        // (script tail, substrings the message must contain)
        (
            "[[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nradius = -1.0\nstrength = 1.0\nprofile = \"gaussian\"\nsteps = 1\n",
            vec!["op[0].radius", "positive"],
        ),
        (
            "[[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nradius = 0.01\nstrength = 1.0\nprofile = \"table\"\nsteps = 1\n",
            vec!["op[0].profile", "table"],
        ),
        (
            "[[op]]\nkind = \"rope\"\npath = []\nradius = 0.01\nstrength = 1.0\nprofile = \"gaussian\"\nsteps = 1\n",
            vec!["op[0].path", "at least one"],
        ),
        (
            "[[op]]\nkind = \"paint\"\nobject = \"nope\"\ncenter = [0.0, 0.0, 0.0]\ncolor = [1, 2, 3]\nradius = 0.01\n",
            vec!["op[0].object", "nope"],
        ),
        (
            "[[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nstrength = 1.0\nprofile = \"gaussian\"\nsteps = 1\n",
            vec!["radius", "line"],
        ),
        (
            "[[op]]\nkind = \"relax\"\nsteps = 1\ncolour = 3\n",
            vec!["colour", "line"],
        ),
        ("[[op]]\nkind = \"twist\"\n", vec!["twist", "line"]),
        (
            "[[op]]\nkind = \"csg\"\nop = \"union\"\na = \"ball\"\nb = \"ball\"\nresult = \"ball\"\n",
            vec!["op[0].result", "already exists"],
        ),
    ];
    for (tail, needles) in cases {
        let msg = error_of(tail);
        for n in needles {
            assert!(msg.contains(n), "`{msg}` lacks `{n}` for:\n{tail}");
        }
    }
    let bad_region = BASE.replace("max = [0.03, 0.03, 0.07]", "max = [0.03, -0.05, 0.07]");
    let msg = Script::parse(&bad_region).unwrap_err().to_string();
    assert!(msg.contains("region.max"), "{msg}");
    let bad_node =
        format!("{BASE}node = {{ mass = 0.0, damping = 0.1, stiffness = 1.0, anchor = 1.0 }}\n");
    let msg = Script::parse(&bad_node).unwrap_err().to_string();
    assert!(msg.contains("region.node") && msg.contains("mass"), "{msg}");
}

#[test]
fn a_small_session_writes_points_and_meshes() {
    let script = Script::parse(&format!(
        "mesh_resolution = 24\n{BASE}[[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nradius = 0.015\n\
         strength = 0.3\nprofile = \"gaussian\"\nsteps = 30\n[[op]]\nkind = \"end_stroke\"\n"
    ))
    .unwrap();
    let out = std::env::temp_dir().join(format!("sculpt-test-{}", std::process::id()));
    let report = run_script(&script, std::path::Path::new("."), &out).unwrap();
    assert_eq!(report.ops.len(), 2);
    assert_eq!(report.objects.len(), 1);
    assert!(report.objects[0].triangles > 100);
    for f in ["ball.ply", "ball_mesh.ply", "report.json"] {
        assert!(out.join(f).metadata().unwrap().len() > 0, "{f}");
    }
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn non_finite_and_inconsistent_values_are_caught_before_any_work() {
    // Each used to pass `Script::validate` and fail (or silently do nothing) only when the op
    // ran, after every object had been fitted, with a message naming no op field.
    let rope = "[[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nradius = 0.01\nstrength = 1.0\nprofile = \"gaussian\"\nsteps = 2\n";
    let paint = "[[op]]\nkind = \"paint\"\nobject = \"ball\"\ncolor = [1, 2, 3]\nradius = 0.01\n";
    let cases = [
        (
            format!("{rope}path_end = [[nan, 0.0, 0.05]]\n"),
            vec!["op[0].path_end[0]", "finite"],
        ),
        (
            format!("{rope}path_end = [[inf, 0.0, 0.05]]\n"),
            vec!["op[0].path_end[0]", "finite"],
        ),
        (
            format!("{paint}center = [nan, 0.0, 0.0]\n"),
            vec!["op[0].center", "finite"],
        ),
        (
            format!("{paint}center = [0.0, 0.0, 0.0]\nforce = inf\n"),
            vec!["op[0].force", "finite"],
        ),
        (
            format!("{paint}center = [0.0, 0.0, 0.0]\nradius_per_newton = -1.0\n"),
            vec!["op[0].radius_per_newton"],
        ),
        (
            format!("{paint}center = [0.0, 0.0, 0.0]\nradius_per_newton = nan\n"),
            vec!["op[0].radius_per_newton"],
        ),
    ];
    for (tail, needles) in cases {
        let msg = error_of(&tail);
        for n in needles {
            assert!(msg.contains(n), "`{msg}` lacks `{n}` for:\n{tail}");
        }
    }
    // An emboss mapping with a zero axis moved nothing, silently.
    let msg = error_of(
        "[[op]]\nkind = \"emboss\"\nobject = \"ball\"\nimage = \"x.png\"\ndepth = 0.001\n\
         mapping = { kind = \"planar\", origin = [0.0, 0.0, 0.0], u_axis = [0.0, 0.0, 0.0], v_axis = [0.0, 0.06, 0.0] }\n",
    );
    assert!(msg.contains("op[0].mapping"), "{msg}");
    // Generated shapes that sample no valid surface (as `workstation fit` rejects them).
    for (generate, needle) in [
        (
            "{ shape = \"torus\", size = 0.05, size2 = 0.08, points = 800 }",
            "object[1].generate.size2",
        ),
        (
            "{ shape = \"box\", size = 0.05, size2 = 0.08, points = 800 }",
            "object[1].generate.size2",
        ),
    ] {
        let msg = error_of(&format!(
            "[[object]]\nname = \"b\"\ngenerate = {generate}\n"
        ));
        assert!(msg.contains(needle), "`{msg}` lacks `{needle}`");
    }
}

/// Largest `| |p| − r |` over the points of `file`.
fn radial_deviation(file: &std::path::Path, r: f64) -> f64 {
    let f = std::fs::File::open(file).unwrap();
    let loaded = sim_core::io::read(std::io::BufReader::new(f), sim_core::io::Format::Ply).unwrap();
    loaded
        .points
        .positions
        .iter()
        .map(|p| (p.length() - r).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_released_rope_leaves_its_ridge_and_spring_back_does_not() {
    // drag.toml as shipped: the rope lets go (plastic commit), 50 relax steps follow.
    let text = EXAMPLES.iter().find(|(n, _)| *n == "drag").unwrap().1;
    let text = text.replace("steps = 150", "steps = 60");
    let tmp = std::env::temp_dir().join(format!("sculpt-drag-{}", std::process::id()));
    let kept = run_script(
        &Script::parse(&text).unwrap(),
        std::path::Path::new("."),
        &tmp,
    );
    kept.unwrap();
    let ridge = radial_deviation(&tmp.join("ball.ply"), 0.05);
    // Static bump of a constant rope: strength / anchor = 0.3 N / 100 N/m = 3 mm.
    assert!(ridge > 1.5e-3, "ridge after release and relax: {ridge:e} m");
    let elastic = text.replace(
        "profile = \"constant\"\n",
        "profile = \"constant\"\nrelease = \"spring_back\"\n",
    );
    // Without the commit, 50 relax steps let the ridge fall back most of the way.
    let script = Script::parse(&elastic.replace("steps = 50", "steps = 400")).unwrap();
    run_script(&script, std::path::Path::new("."), &tmp).unwrap();
    let back = radial_deviation(&tmp.join("ball.ply"), 0.05);
    assert!(
        back < ridge / 3.0,
        "spring back left {back:e} m (ridge {ridge:e} m)"
    );
    let _ = std::fs::remove_dir_all(&tmp);
}

#[test]
fn counts_over_their_caps_name_the_field_and_the_limit() {
    let msg = Script::parse(&BASE.replace("points = 800", "points = 20000001"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        msg,
        "object[0].generate.points: 20000001 is over the limit of 20000000 points (MAX_GEN_POINTS)"
    );
    let rope = "[[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nradius = 0.01\nstrength = 1.0\nprofile = \"gaussian\"\n";
    let msg = error_of(&format!("{rope}steps = 1000001\n"));
    assert_eq!(
        msg,
        "op[0].steps: 1000001 is over the limit of 1000000 steps (MAX_STEPS)"
    );
    let msg = error_of("[[op]]\nkind = \"relax\"\nsteps = 1000001\n");
    assert!(
        msg.starts_with("op[0].steps: 1000001") && msg.contains("(MAX_STEPS)"),
        "{msg}"
    );
    assert!(
        Script::parse(&format!(
            "{BASE}[[op]]\nkind = \"relax\"\nsteps = 1000000\n"
        ))
        .is_ok()
    );
}

/// An ASCII PLY of `n` points on a sphere of radius `r` (a Fibonacci lattice) with their
/// normals, each written `copies` times.
fn sphere_ply(n: usize, r: f64, copies: usize) -> String {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n",
        n * copies
    );
    for _ in 0..copies {
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let a = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let (s, c) = ((1.0 - z * z).sqrt(), a.cos());
            let (x, y) = (s * c, s * a.sin());
            text += &format!("{} {} {} {x} {y} {z}\n", r * x, r * y, r * z);
        }
    }
    text
}

#[test]
fn a_file_that_repeats_its_points_sculpts_like_one_that_does_not() {
    // A mesh file repeats a vertex wherever its normals or texture split. Loaded as given,
    // the repeats made the object's spacing 0 (paint's rim points failed on it), and after a
    // rope stroke paint found no trusted surface for rim points at all: they are merged.
    let dir = std::env::temp_dir().join(format!("sculpt-repeats-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut added = Vec::new();
    for copies in [1, 2] {
        std::fs::write(dir.join("ball.ply"), sphere_ply(1500, 0.05, copies)).unwrap();
        let script = Script::parse(
            "mesh_resolution = 24\n[[object]]\nname = \"ball\"\nfile = \"ball.ply\"\n\
             [region]\nobject = \"ball\"\nmin = [-0.03, -0.03, 0.02]\nmax = [0.03, 0.03, 0.07]\n\
             spacing = 0.003\nband = 0.008\n\
             [[op]]\nkind = \"rope\"\npath = [[0.0, 0.0, 0.05]]\nradius = 0.015\n\
             strength = 0.3\nprofile = \"gaussian\"\nsteps = 60\n[[op]]\nkind = \"end_stroke\"\n\
             [[op]]\nkind = \"paint\"\nobject = \"ball\"\ncenter = [0.0, 0.0, 0.053]\n\
             color = [200, 0, 0]\nradius = 0.012\n",
        )
        .unwrap();
        let report = run_script(&script, &dir, &dir.join("out"))
            .unwrap_or_else(|e| panic!("{copies} copies: {e:#}"));
        let summary = &report.ops[2].summary;
        let rim: usize = summary
            .split(", ")
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("{summary}"));
        added.push((rim, report.objects[0].points));
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(added[0].0 > 0, "{added:?}");
    assert_eq!(added[0], added[1], "rim points added and points written");
}

/// A UV sphere of radius `r`: `around` × (`rings` − 1) vertices plus the poles, wound
/// counter-clockwise from outside.
fn uv_sphere(r: f64, around: u32, rings: u32) -> sim_core::mesh::TriMesh {
    use glam::DVec3;
    let mut vertices = vec![DVec3::Z * r, -DVec3::Z * r];
    for i in 1..rings {
        let polar = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..around {
            let a = std::f64::consts::TAU * j as f64 / around as f64;
            vertices
                .push(r * DVec3::new(polar.sin() * a.cos(), polar.sin() * a.sin(), polar.cos()));
        }
    }
    let at = |i: u32, j: u32| 2 + (i - 1) * around + j % around;
    let mut triangles = Vec::new();
    for j in 0..around {
        triangles.push([0, at(1, j), at(1, j + 1)]);
        triangles.push([1, at(rings - 1, j + 1), at(rings - 1, j)]);
        for i in 1..rings - 1 {
            triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    sim_core::mesh::TriMesh {
        vertices,
        normals: Vec::new(),
        triangles,
    }
}

/// An object read from `file`, as given (no size, no offset).
fn file_object(name: &str, file: &str) -> super::script::ObjectSpec {
    super::script::ObjectSpec {
        name: name.into(),
        file: Some(file.into()),
        generate: None,
        size: None,
        offset: [0.0; 3],
    }
}

#[test]
fn a_mesh_file_is_loaded_with_each_vertex_once_and_its_winding_normals() {
    // An STL gives every triangle its own three corners and no vertex normals: loaded as given,
    // a scene saw each vertex six times, and estimated normals where the winding says which
    // way is out.
    let dir = std::env::temp_dir().join(format!("sculpt-stl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sphere = uv_sphere(0.05, 32, 16);
    let file = std::fs::File::create(dir.join("ball.stl")).unwrap();
    sim_core::io::write_mesh(file, &sphere, sim_core::io::Format::Stl).unwrap();
    let spec = file_object("ball", "ball.stl");
    let object = super::load_object(&spec, &dir, &sim_core::FitParams::default()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(object.positions.len(), sphere.vertices.len());
    let winding = sphere.vertex_normals();
    for (p, n) in object.positions.iter().zip(&object.normals) {
        // The STL holds f32 positions: find the vertex it came from.
        let v = sphere
            .vertices
            .iter()
            .position(|v| (*v - *p).length() < 1e-7)
            .unwrap();
        assert!(
            (*n - winding[v]).length() < 1e-6,
            "{p}: {n} against {}",
            winding[v]
        );
    }
}

#[test]
fn a_file_with_unoriented_normals_opens_with_them_made_consistent() {
    // Some scanners write normals whose signs are noise; fitted as given, the field has no
    // consistent inside and the surface breaks up.
    let dir = std::env::temp_dir().join(format!("sculpt-unoriented-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut ball = sim_core::sampling::Shape::Sphere { radius: 0.05 }.sample(2000, 3);
    let normals = ball.normals.as_mut().unwrap();
    for (i, n) in normals.iter_mut().enumerate() {
        if (i * 7919) % 13 < 6 {
            *n = -*n;
        }
    }
    let file = std::fs::File::create(dir.join("scan.ply")).unwrap();
    sim_core::io::write_points_ply(file, &ball, false).unwrap();
    let spec = file_object("scan", "scan.ply");
    let object = super::load_object(&spec, &dir, &sim_core::FitParams::default()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    for (p, n) in object.positions.iter().zip(&object.normals) {
        assert!(p.dot(*n) > 0.0, "{p}: {n} faces in");
    }
    // Inside is negative, outside positive, and the surface is where the points are.
    assert!(object.field.value(glam::DVec3::ZERO) < 0.0);
    assert!(object.field.value(glam::DVec3::new(0.0, 0.0, 0.08)) > 0.0);
    let worst = object
        .positions
        .iter()
        .map(|&p| object.field.value(p).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3, "field at the points: {worst}");
}
