//! `workstation fit` end to end, through the library entry point (no process spawned).

use clap::Parser;

use super::*;

#[derive(Debug, Parser)]
struct Cli {
    #[command(flatten)]
    fit: FitArgs,
}

fn args(line: &[&str]) -> FitArgs {
    Cli::parse_from(std::iter::once("fit").chain(line.iter().copied())).fit
}

#[test]
fn generated_sphere_reports_the_checked_json_fields() {
    let dir = std::env::temp_dir().join(format!("ws-fit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = dir.join("sphere.stl");
    let a = args(&[
        "gen:sphere:2:3000",
        "--json",
        "--mesh",
        mesh.to_str().unwrap(),
        "--resolution",
        "32",
    ]);
    let report = run(&a).unwrap();
    let json: serde_json::Value = serde_json::to_value(&report).unwrap();
    for key in [
        "points",
        "construct_s",
        "projected_rms_error",
        "projected_max_error",
        "surface",
        "local_fields",
        "gap_fields",
        "gap_samples",
    ] {
        assert!(json.get(key).is_some_and(|v| !v.is_null()), "missing {key}");
    }
    assert_eq!(report.points, 3000);
    assert!(
        report.gap_fields < report.local_fields,
        "gap fields are among the fields"
    );
    assert_eq!(report.gap_samples, 0, "off by default");
    assert_eq!(report.error_samples, 10_000);
    assert_eq!(
        report.reference_size,
        Some(2.0),
        "relative to R for a sphere"
    );
    assert!(report.projected_rms_error.unwrap() < 1e-3);
    // The surface error comes broken down by distance from the nearest input point too.
    let bands = json["surface"]["by_spacing"]["bands"].as_array().unwrap();
    assert_eq!(bands.len(), 6, "{json}");
    let share: f64 = bands
        .iter()
        .map(|b| b["coverage"]["samples"].as_f64().unwrap())
        .sum();
    assert!((share - 1.0).abs() < 1e-9, "{json}");
    // The mesh file reads back with the triangles reported.
    let back = read_file(&mesh).unwrap().mesh.unwrap();
    assert_eq!(Some(back.triangles.len()), report.mesh_triangles);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn file_input_with_faces_measures_against_its_own_mesh() {
    let dir = std::env::temp_dir().join(format!("ws-fit-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A sphere mesh made by fitting, written as PLY, read back as input.
    let mesh_path = dir.join("in.ply");
    run(&args(&[
        "gen:sphere:1:2000",
        "--quiet",
        "--mesh",
        mesh_path.to_str().unwrap(),
        "--resolution",
        "24",
    ]))
    .unwrap();
    let report = run(&args(&[
        mesh_path.to_str().unwrap(),
        "--quiet",
        "--normals",
        "estimate",
    ]))
    .unwrap();
    assert_eq!(report.reference.as_deref(), Some("input mesh"));
    assert!(report.projected_max_error.unwrap() < 0.05, "{report:?}");
    let none = run(&args(&[
        mesh_path.to_str().unwrap(),
        "--quiet",
        "--reference",
        "none",
    ]))
    .unwrap();
    assert!(none.reference.is_none() && none.projected_rms_error.is_none());
    assert!(run(&args(&["missing.ply"])).is_err());
    assert!(run(&args(&["gen:sphere:1:100", "--reference", "mesh:nope.obj"])).is_err());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_noise_is_an_error_naming_the_flag() {
    // `--noise nan` used to fail as "point 0 has a non-finite coordinate".
    for v in ["nan", "inf", "-0.1"] {
        let a = args(&["gen:sphere:1:200", "--quiet", &format!("--noise={v}")]);
        let msg = format!("{:#}", run(&a).unwrap_err());
        assert!(msg.contains("--noise"), "{v}: {msg}");
    }
}

#[derive(Debug, Parser)]
struct MeshErrorCli {
    #[command(flatten)]
    args: MeshErrorArgs,
}

fn mesh_error_args(line: &[&str]) -> MeshErrorArgs {
    MeshErrorCli::parse_from(std::iter::once("mesh-error").chain(line.iter().copied())).args
}

#[test]
fn mesh_error_measures_fits_mesh_like_fit_does_and_names_bad_input() {
    let dir = std::env::temp_dir().join(format!("ws-mesh-error-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = dir.join("sphere.ply");
    let points = dir.join("points.ply");
    let fit = run(&args(&[
        "gen:sphere:1:3000",
        "--quiet",
        "--points-out",
        points.to_str().unwrap(),
        "--mesh",
        mesh.to_str().unwrap(),
        "--resolution",
        "48",
        "--surface-samples",
        "20000",
    ]))
    .unwrap();
    let m = mesh.to_str().unwrap();
    let r = run_mesh_error(&mesh_error_args(&[
        m,
        "--reference",
        "sphere:1",
        "--samples",
        "20000",
    ]))
    .unwrap();
    // The same metric and samples as fit's `surface` (the file stores f32 vertices).
    let surface = fit.surface.unwrap();
    assert!(
        (r.to_reference.max - surface.to_reference.max).abs() < 1e-6,
        "{r:?} {surface:?}"
    );
    assert!(
        (r.coverage.rms - surface.coverage.rms).abs() < 1e-6,
        "{r:?} {surface:?}"
    );
    assert!(r.to_reference.max < 1e-3 && r.coverage.max < 1e-2, "{r:?}");
    assert_eq!(Some(r.triangles), fit.mesh_triangles);
    // A closed sphere: one piece, no open edge, as `fit` counted them too.
    let profile = fit.mesh_profile.as_ref().unwrap();
    assert_eq!((r.pieces, r.open_edges), (1, 0), "{r:?}");
    assert_eq!((profile.components, profile.open_edges), (1, 0));
    assert!(profile.cut_pieces.is_empty(), "{:?}", profile.cut_pieces);
    assert_eq!((r.reference_pieces, r.reference_open_edges), (None, None));
    let json = serde_json::to_value(&r).unwrap();
    assert!(json.get("by_spacing").is_none(), "{json}");
    // With the points: the same samples, broken down by distance from the nearest point.
    let p = points.to_str().unwrap();
    let line = [
        m,
        "--reference",
        "sphere:1",
        "--samples",
        "20000",
        "--points",
        p,
    ];
    let by = run_mesh_error(&mesh_error_args(&line)).unwrap();
    assert_eq!(by.to_reference, r.to_reference);
    let json = serde_json::to_value(&by).unwrap();
    let bands = json["by_spacing"]["bands"].as_array().unwrap();
    assert_eq!(bands.len(), 6, "{json}");
    for side in ["to_reference", "coverage"] {
        let share: f64 = bands
            .iter()
            .map(|b| b[side]["samples"].as_f64().unwrap())
            .sum();
        assert!((share - 1.0).abs() < 1e-9, "{json}");
    }
    // 3000 random points on a unit sphere lie some 0.03 apart.
    let spacing = json["by_spacing"]["spacing"].as_f64().unwrap();
    assert!(spacing > 0.005 && spacing < 0.06, "{spacing}");
    let lone = dir.join("lone.xyz");
    std::fs::write(&lone, "0 0 1\n").unwrap();
    // Against the wrong radius both directions see the 10 % offset.
    let off = run_mesh_error(&mesh_error_args(&[m, "--reference", "sphere:1.1"])).unwrap();
    assert!(
        off.to_reference.rms > 0.08 && off.coverage.rms > 0.08,
        "{off:?}"
    );
    for (line, needle) in [
        (
            vec![m, "--reference", "sphere:1", "--samples", "0"],
            "--samples",
        ),
        (vec![m, "--reference", "none"], "needs a reference"),
        (vec![m, "--reference", "cube:1"], "unknown shape"),
        (
            vec!["missing.ply", "--reference", "sphere:1"],
            "missing.ply",
        ),
        (
            vec![m, "--reference", "sphere:1", "--points", "nowhere.ply"],
            "nowhere.ply",
        ),
        (
            vec![
                m,
                "--reference",
                "sphere:1",
                "--points",
                lone.to_str().unwrap(),
            ],
            "needs two distinct points",
        ),
    ] {
        let msg = format!("{:#}", run_mesh_error(&mesh_error_args(&line)).unwrap_err());
        assert!(msg.contains(needle), "{line:?}: {msg}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn error_samples_over_the_cap_is_a_named_error() {
    let e = run(&args(&["gen:sphere:1:100", "--error-samples", "10000001"]))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "--error-samples = 10000001 is over the limit of 10000000 samples (MAX_SURFACE_SAMPLES)"
    );
}

/// A point file whose normals' signs are noise (as some scanners write them) is fitted with
/// them made consistent, on the fit's own k-NN graph: a whole sphere, near the truth.
#[test]
fn file_with_unoriented_normals_fits_whole() {
    let dir = std::env::temp_dir().join(format!("ws-fit-unoriented-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut sphere = sim_core::sampling::Shape::Sphere { radius: 1.0 }.sample(4000, 7);
    for (i, n) in sphere.normals.as_mut().unwrap().iter_mut().enumerate() {
        if (i * 7919) % 13 < 6 {
            *n = -*n;
        }
    }
    let path = dir.join("scrambled.ply");
    let file = File::create(&path).unwrap();
    io::write_points_ply(BufWriter::new(file), &sphere, false).unwrap();
    let mesh = dir.join("out.ply");
    let report = run(&args(&[
        path.to_str().unwrap(),
        "--quiet",
        "--reference",
        "sphere:1",
        "--resolution",
        "40",
        "--mesh",
        mesh.to_str().unwrap(),
    ]))
    .unwrap();
    assert!(report.projected_rms_error.unwrap() < 2e-3, "{report:?}");
    assert_eq!(report.mesh_profile.as_ref().unwrap().components, 1);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn gap_samples_are_reported_off_on_request_and_bounded() {
    let run_with = |value: &str| {
        run(&args(&[
            "gen:sphere:1:2000",
            "--quiet",
            "--error-samples",
            "0",
            "--surface-samples",
            "0",
            "--gap-samples",
            value,
        ]))
    };
    let on = run_with("0.3").unwrap();
    let off = run_with("0").unwrap();
    // A random sampling leaves gaps.
    assert!(on.gap_samples > 0);
    assert_eq!(off.gap_samples, 0);
    // The samples get fields where the thinning gives them one.
    assert!(on.local_fields > off.local_fields);
    assert_eq!(
        (on.points, off.points),
        (2000, 2000),
        "the points stay the input's"
    );
    let err = format!("{:#}", run_with("1.5").unwrap_err());
    assert!(err.contains("gap_samples must be in [0, 1)"), "{err}");
}
