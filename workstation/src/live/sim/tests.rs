//! The simulation core's tests: strokes, run-time settings, operations between strokes.

use glam::{DQuat, DVec3};
use sim_core::csg::CsgOp;

use super::*;
use crate::live::scene_file::{MODEL_SIZE_M, SceneFile, ToolKind};
use crate::live::shared::{ForceTool, InputEvent};
use crate::sculpt::script::Op;

fn core(selected: &str) -> SimCore {
    let scene = SceneFile::parse(&format!(
        r#"
[[object]]
name = "ball"
generate = {{ shape = "sphere", size = 0.05, points = 2000, seed = 2 }}
[region]
object = "ball"
min = [-0.05, 0.0, -0.05]
max = [0.05, 0.06, 0.05]
spacing = 0.0025
band = 0.008
[tools]
selected = "{selected}"
rope = {{ radius = 0.01, stiffness = 60.0, max_force = 3.0 }}
"#
    ))
    .unwrap();
    SimCore::new(&scene, ".".into()).unwrap()
}

fn at(p: DVec3, buttons: u16) -> InputEvent {
    InputEvent {
        position: p,
        velocity: DVec3::ZERO,
        orientation: DQuat::IDENTITY,
        buttons,
        force: DVec3::ZERO,
        contact: None,
    }
}

fn lift_near(core: &SimCore, c: DVec3) -> f64 {
    core.scene().objects()[0]
        .positions
        .iter()
        .filter(|p| p.distance(c) < 0.006)
        .map(|p| p.length() - 0.05)
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn a_curve_rope_pulls_along_the_tips_path_and_the_shape_stays() {
    let mut c = core("rope_curve");
    // Press above the surface, slide 4 cm over it 8 mm out, release.
    let (a, b) = (DVec3::new(-0.02, 0.05, 0.0), DVec3::new(0.02, 0.05, 0.0));
    let to_surface = |p: DVec3| p.normalize() * 0.058;
    c.input(&at(to_surface(a), 1)).unwrap();
    for k in 0..=400 {
        let p = to_surface(a.lerp(b, k as f64 / 400.0));
        c.input(&at(p, 1)).unwrap();
        c.step(1e-3).unwrap();
        if k % 2 == 0 {
            c.follow().unwrap();
        }
    }
    c.input(&at(to_surface(b), 0)).unwrap();
    for _ in 0..50 {
        c.step(1e-3).unwrap();
    }
    c.follow().unwrap();
    assert_eq!(c.strokes().len(), 1);
    // Both ends and the middle of the path rose, not only where it was pressed.
    for x in [-0.02, 0.0, 0.02] {
        let p = DVec3::new(x, 0.05, 0.0).normalize() * 0.05;
        let lift = lift_near(&c, p);
        assert!(
            lift > 1e-3,
            "surface under the curve at x = {x}: {lift:e} m"
        );
    }
}

#[test]
fn settings_change_at_run_time_and_bad_ones_name_the_field() {
    let mut c = core("touch");
    let mut s = c.settings();
    s.tools.rope.stiffness = 120.0;
    s.tools.probe.semi_axes = [0.004, 0.004, 0.006];
    c.configure(&s).unwrap();
    assert_eq!(c.settings().tools.rope.stiffness, 120.0);
    c.select(ToolKind::ProbePush);
    assert_eq!(c.force_tool(), ForceTool::Probe(s.tools.probe));
    // A new material, integrator and step reopen the region; stepping goes on.
    s.material.stiffness = 20.0;
    s.integrator = "backward_euler".into();
    s.dt = 2e-3;
    c.configure(&s).unwrap();
    c.step(2e-3).unwrap();
    assert!(c.publish_field().is_some());
    assert_eq!(c.settings(), s);
    let mut bad = s.clone();
    bad.tools.rope.stiffness = -1.0;
    let e = c.configure(&bad).unwrap_err();
    assert!(format!("{e:#}").contains("tools.rope.stiffness"), "{e:#}");
    assert_eq!(c.settings(), s, "nothing changed");
}

#[test]
fn a_primitive_carves_at_the_cursor_and_a_saved_scene_reloads_the_result() {
    let mut c = core("touch");
    let top = DVec3::new(0.0, 0.05, 0.0);
    let (kind, _) = c
        .csg_primitive(CsgOp::Difference, "sphere", 0.01, top)
        .unwrap();
    assert_eq!(kind, "csg");
    let near = c
        .visible()
        .flat_map(|o| o.positions.iter())
        .filter(|p| p.distance(top) < 0.007)
        .count();
    assert_eq!(near, 0, "points left inside the carved sphere");
    assert!(c.csg_primitive(CsgOp::Union, "cone", 0.01, top).is_err());
    assert!(
        c.csg_primitive(CsgOp::Union, "sphere", 0.01, DVec3::NAN)
            .is_err()
    );
    let dir = std::env::temp_dir().join(format!("ws-save-scene-{}", std::process::id()));
    let path = c.save_scene(&dir).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let scene = SceneFile::parse(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let again = SimCore::new(&scene, dir.clone()).unwrap();
    let count = |c: &SimCore| c.visible().map(|o| o.positions.len()).sum::<usize>();
    assert_eq!(count(&again), count(&c));
    assert_eq!(again.settings(), c.settings());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_failed_operation_leaves_the_scene_usable() {
    let mut c = core("touch");
    let bad: Op = toml::from_str(
        "kind = \"csg\"\nop = \"union\"\na = \"ball\"\nb = \"nothing\"\nresult = \"r\"",
    )
    .unwrap();
    assert!(c.run_op(&bad).is_err());
    c.step(1e-3).unwrap();
    assert!(c.publish_field().is_some(), "the region is open again");
}

/// A probe pull from 1 mm inside the top-left of the ball outward along its normal to
/// `out_mm` beyond the surface (1 s), released there: the committed core and the largest height
/// of the points near the pull (mm), and the worst |committed field| at those points (mm).
fn probe_pull(out_mm: f64) -> (SimCore, f64, f64) {
    let scene = SceneFile::parse(
        r#"
[[object]]
name = "ball"
generate = { shape = "sphere", size = 0.05, points = 3000, seed = 2 }
[region]
object = "ball"
min = [-0.05, 0.0, -0.05]
max = [0.05, 0.06, 0.05]
spacing = 0.0025
band = 0.008
[tools]
selected = "probe_pull"
probe = { semi_axes = [0.009, 0.009, 0.009], surface_stiffness = 2e6, sculpt_stiffness = 1000.0 }
"#,
    )
    .unwrap();
    let mut c = SimCore::new(&scene, ".".into()).unwrap();
    let dir = DVec3::new(-1.0, 2.0, -1.0).normalize();
    let (a, b) = (dir * 0.049, dir * (0.05 + out_mm * 1e-3));
    c.input(&at(a, 1)).unwrap();
    for k in 0..=1000 {
        c.input(&at(a.lerp(b, k as f64 / 1000.0), 1)).unwrap();
        c.step(1e-3).unwrap();
        if k % 2 == 0 {
            c.follow().unwrap();
        }
    }
    c.input(&at(b, 0)).unwrap();
    assert_eq!(c.strokes().len(), 1);
    let o = &c.scene().objects()[0];
    let near: Vec<DVec3> = o
        .positions
        .iter()
        .copied()
        .filter(|p| p.distance(dir * 0.05) < 0.01)
        .collect();
    let height = near
        .iter()
        .map(|p| p.length() - 0.05)
        .fold(f64::NEG_INFINITY, f64::max);
    let off = near
        .iter()
        .map(|&p| o.field.value(p).abs())
        .fold(0.0, f64::max);
    (c, height * 1e3, off * 1e3)
}

#[test]
fn a_probe_pull_commits_a_bump_whose_points_lie_on_the_field() {
    // Released with the probe 6 mm out, holding the material: a bump, resampled like every
    // other stroke (points inserted on its flanks).
    let (c, height, off) = probe_pull(6.0);
    let r = &c.strokes()[0].resampled;
    eprintln!("6 mm: {height:.2} mm high, {off:.3} mm off; {r:?}");
    assert!(height > 4.0, "{height} mm");
    assert!(r.inserted > 20, "{r:?}");
    assert!(off < 0.25, "a point {off} mm off the committed surface");
    // The region's band (8 mm) follows the surface: nothing was cut flat.
    let summary = &c.strokes()[0].summary;
    assert!(!summary.contains("cut flat"), "{summary}");
    // Pulled 13.7 mm out: the points must lie on whatever the committed field holds (before
    // the commit resampled probe pulls, followers stood 6.9 mm out, on no surface).
    let (_, height, off) = probe_pull(13.7);
    eprintln!("13.7 mm: {height:.2} mm high, {off:.3} mm off");
    assert!(off < 0.25, "a point {off} mm off the committed surface");
}

#[test]
fn another_stations_csg_result_is_added_shown_and_sculpted_and_its_name_is_not_reused() {
    // Station a carves a sphere out of the ball: a new object, the ball and the primitive
    // hidden, the region on the result.
    let mut a = core("touch");
    let top = DVec3::new(0.0, 0.05, 0.0);
    a.csg_primitive(CsgOp::Difference, "sphere", 0.01, top)
        .unwrap();
    let state = SharedPoints {
        version: 2,
        ..a.shared_points()
    };
    assert_eq!(state.visible, std::slice::from_ref(&state.object));
    // Station b, on the same scene file, takes it: the same points, shown alone, sculpted.
    let mut b = core("touch");
    b.adopt(&state).unwrap();
    let mine = b.shared_points();
    assert_eq!(mine.object, state.object);
    assert_eq!(mine.positions, state.positions);
    assert_eq!(mine.colors, state.colors);
    assert_eq!(mine.visible, state.visible);
    let shown: Vec<_> = b.visible().map(|o| o.positions.len()).collect();
    assert_eq!(shown, [state.positions.len()]);
    // Taking it again (a repeat) changes nothing; a result named like an object is refused.
    b.adopt(&state).unwrap();
    assert_eq!(b.shared_points().positions, state.positions);
    let again = Op::Csg {
        op: CsgOp::Union,
        a: "ball".into(),
        b: state.object.clone(),
        result: state.object.clone(),
    };
    let e = b.run_op(&again).unwrap_err().to_string();
    assert!(e.contains("already called"), "{e}");
    assert_eq!(b.shared_points().positions, state.positions);
}

#[test]
fn a_model_file_opens_as_its_own_scene_scaled_to_the_demo_ball_and_centred() {
    // A scan in millimetres, 60 across and far from the origin.
    let dir = std::env::temp_dir().join(format!("model-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut scan = sim_core::sampling::Shape::Sphere { radius: 30.0 }.sample(1500, 3);
    scan.positions
        .iter_mut()
        .for_each(|p| *p += DVec3::new(100.0, -40.0, 250.0));
    let path = dir.join("my scan.v2.PLY");
    let file = std::fs::File::create(&path).unwrap();
    sim_core::io::write_points_ply(std::io::BufWriter::new(file), &scan, false).unwrap();
    let scene = crate::live::scene_file::load_scene(&path).unwrap();
    assert_eq!(scene.object.len(), 1);
    assert_eq!(
        scene.object[0].name, "my_scan_v2",
        "output files are named after it"
    );
    assert_eq!(scene.region.object, "my_scan_v2");
    let core = SimCore::new(&scene, dir.clone()).unwrap();
    // Saved, it reloads as an ordinary scene in those scene metres.
    let saved = core.save_scene(&dir.join("saved")).unwrap();
    let again = SimCore::new(
        &crate::live::scene_file::load_scene(&saved).unwrap(),
        dir.join("saved"),
    )
    .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(
        again.scene.objects()[0].positions,
        core.scene.objects()[0].positions
    );
    let positions = &core.scene.objects()[0].positions;
    let (lo, hi) = sim_core::pointset::bounds(positions).unwrap();
    let side = (hi - lo).max_element();
    assert!((side - MODEL_SIZE_M).abs() < 1e-12, "longest side {side}");
    assert!(((lo + hi) * 0.5).length() < 1e-12, "centred: {lo} … {hi}");
    // The region holds all of it with room around.
    let (rmin, rmax) = (DVec3::from(scene.region.min), DVec3::from(scene.region.max));
    assert!(rmin.cmplt(lo - 0.01).all() && rmax.cmpgt(hi + 0.01).all());
}

#[test]
fn size_scales_a_file_and_only_a_file() {
    let scene = |object: &str| {
        SceneFile::parse(&format!(
            "[[object]]\nname = \"a\"\n{object}\n[region]\nobject = \"a\"\nmin = [-1, -1, -1]\n\
             max = [1, 1, 1]\nspacing = 0.1\nband = 0.2\n"
        ))
        .map(|_| ())
        .unwrap_err()
        .to_string()
    };
    let msg = scene("generate = { shape = \"sphere\", size = 0.05, points = 500 }\nsize = 0.1");
    assert!(
        msg.contains("object[0].size") && msg.contains("generate.size"),
        "{msg}"
    );
    let msg = scene("file = \"a.ply\"\nsize = -1.0");
    assert!(
        msg.contains("object[0].size") && msg.contains("positive"),
        "{msg}"
    );
}
