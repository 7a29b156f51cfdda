//! File formats: round trips, the common dialects, and malformed input as errors, never panics.

use glam::DVec3;
use sim_core::PointSet;
use sim_core::io::{self, Format, IoError};
use sim_core::mesh::TriMesh;

fn sample_points() -> PointSet {
    let positions = vec![
        DVec3::new(1.0, -2.5, 3.25),
        DVec3::new(1e-7, 4e3, -0.5),
        DVec3::ZERO,
    ];
    let normals = vec![DVec3::X, DVec3::new(0.0, 0.6, 0.8), DVec3::NEG_Z];
    PointSet {
        positions,
        normals: Some(normals),
        colors: Some(vec![[255, 0, 7], [1, 2, 3], [9, 9, 9]]),
    }
}

#[test]
fn ply_round_trip_binary_and_ascii() {
    let pts = sample_points();
    for ascii in [false, true] {
        let mut buf = Vec::new();
        io::write_points_ply(&mut buf, &pts, ascii).unwrap();
        let back = io::read(&buf[..], Format::Ply).unwrap().points;
        assert_eq!(
            back.positions, pts.positions,
            "positions are written as doubles"
        );
        assert_eq!(back.colors, pts.colors);
        for (a, b) in back
            .normals
            .unwrap()
            .iter()
            .zip(pts.normals.as_ref().unwrap())
        {
            assert!((*a - *b).length() < 1e-6);
        }
    }
}

#[test]
fn big_endian_ply_with_faces_and_float_colours() {
    let mut buf = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nproperty float green\nproperty float blue\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n".to_vec();
    for v in [
        [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.5],
        [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    ] {
        for x in v {
            buf.extend_from_slice(&x.to_be_bytes());
        }
    }
    buf.push(3);
    for i in [0u32, 1, 2] {
        buf.extend_from_slice(&i.to_be_bytes());
    }
    let l = io::read(&buf[..], Format::Ply).unwrap();
    assert_eq!(l.points.positions[2], DVec3::Y);
    assert_eq!(l.points.colors.unwrap()[0], [255, 0, 128]);
    assert_eq!(l.mesh.unwrap().triangles, vec![[0, 1, 2]]);
}

#[test]
fn off_obj_xyz_read() {
    let off = "NOFF\n# comment\n4 2 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n1 1 0 0 0 1\n0 1 0 0 0 1\n4 0 1 2 3\n3 0 1 2\n";
    let l = io::read(off.as_bytes(), Format::Off).unwrap();
    assert_eq!(l.points.len(), 4);
    assert_eq!(l.points.normals.unwrap()[3], DVec3::Z);
    assert_eq!(l.mesh.unwrap().triangles.len(), 3);
    let obj = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1//1 2//2 -1//3\n";
    let l = io::read(obj.as_bytes(), Format::Obj).unwrap();
    assert_eq!(l.points.colors.unwrap()[1], [0, 255, 0]);
    assert_eq!(l.mesh.unwrap().triangles, vec![[0, 1, 2]]);
    let xyz = "1 2 3 0 0 1\n4 5 6 1 0 0\n";
    let l = io::read(xyz.as_bytes(), Format::Xyz).unwrap();
    assert_eq!(l.points.positions[1], DVec3::new(4.0, 5.0, 6.0));
    assert_eq!(l.points.normals.unwrap()[1], DVec3::X);
}

#[test]
fn mesh_writers_round_trip() {
    let mesh = TriMesh {
        vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        normals: vec![DVec3::NEG_ONE.normalize(); 4],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    };
    for format in [Format::Ply, Format::Obj, Format::Stl] {
        let mut buf = Vec::new();
        io::write_mesh(&mut buf, &mesh, format).unwrap();
        let back = io::read(&buf[..], format).unwrap().mesh.unwrap();
        assert_eq!(back.triangles.len(), 4, "{format:?}");
        let corner = |m: &TriMesh, t: usize, k: usize| m.vertices[m.triangles[t][k] as usize];
        for t in 0..4 {
            for k in 0..3 {
                assert_eq!(corner(&back, t, k), corner(&mesh, t, k), "{format:?}");
            }
        }
    }
}

#[test]
fn an_stl_is_read_as_one_connected_mesh_with_each_vertex_once() {
    // STL repeats a vertex once per triangle using it. Read as given, a tetrahedron was 12
    // points, each with three twins at distance 0, and 4 separate triangles.
    let tetrahedron = TriMesh {
        vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        normals: Vec::new(),
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    };
    let mut binary = Vec::new();
    io::write_mesh(&mut binary, &tetrahedron, Format::Stl).unwrap();
    // The same in ASCII, with one corner written as −0 (the same position).
    let ascii = "solid t
        facet normal 0 0 -1
outer loop
vertex 0 0 0
vertex 0 1 0
vertex 1 0 0
endloop
endfacet
        facet normal 0 -1 0
outer loop
vertex 0 0 0
vertex 1 0 0
vertex 0 0 1
endloop
endfacet
        facet normal -1 0 0
outer loop
vertex -0 0 0
vertex 0 0 1
vertex 0 1 0
endloop
endfacet
        facet normal 1 1 1
outer loop
vertex 1 0 0
vertex 0 1 0
vertex 0 0 1
endloop
endfacet
        endsolid t
";
    for (bytes, what) in [(&binary[..], "binary"), (ascii.as_bytes(), "ASCII")] {
        let loaded = io::read(bytes, Format::Stl).unwrap();
        let mesh = loaded.mesh.unwrap();
        assert_eq!(mesh.vertices.len(), 4, "{what}");
        assert_eq!(loaded.points.positions, mesh.vertices, "{what}");
        for (t, want) in mesh.triangles.iter().zip(&tetrahedron.triangles) {
            for k in 0..3 {
                let corner = mesh.vertices[t[k] as usize];
                assert_eq!(corner, tetrahedron.vertices[want[k] as usize], "{what}");
            }
        }
        assert_eq!(mesh.components().1, vec![4], "{what}: one piece");
        // Each vertex's normal from the winding is the mean of its three faces', not one
        // facet's.
        let origin = mesh
            .vertices
            .iter()
            .position(|v| *v == DVec3::ZERO)
            .unwrap();
        let n = mesh.vertex_normals()[origin];
        assert!(
            (n - DVec3::NEG_ONE.normalize()).length() < 1e-12,
            "{what}: {n}"
        );
    }
}

#[test]
fn malformed_files_name_the_line_or_record() {
    let cases: [(&[u8], Format, &str); 8] = [
        (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 zz 0\n", Format::Ply, "line 9"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0", Format::Ply, "vertex record 0"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", Format::Ply, "header line 4"),
        (b"plx\n", Format::Ply, "header line 1"),
        (b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", Format::Off, "line 6"),
        (b"v 0 0 0\nv 1 nan 0\n", Format::Obj, "line 2"),
        (b"1 2 3\n4 5\n", Format::Xyz, "line 2"),
        (b"solid x\nvertex 1 2\n", Format::Stl, "line 2"),
    ];
    for (bytes, format, needle) in cases {
        let err = io::read(bytes, format).expect_err("malformed input accepted");
        let msg = err.to_string();
        assert!(
            msg.contains(needle),
            "{format:?}: {msg:?} does not name {needle:?}"
        );
    }
    assert!(matches!(
        io::read(&b""[..], Format::Xyz),
        Err(IoError::Empty)
    ));
}

#[test]
fn truncated_and_corrupted_files_never_panic() {
    let mut files = Vec::new();
    let mut buf = Vec::new();
    io::write_points_ply(&mut buf, &sample_points(), false).unwrap();
    files.push((buf, Format::Ply));
    let mut buf = Vec::new();
    io::write_points_ply(&mut buf, &sample_points(), true).unwrap();
    files.push((buf, Format::Ply));
    files.push((
        b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n".to_vec(),
        Format::Off,
    ));
    files.push((
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec(),
        Format::Obj,
    ));
    for (bytes, format) in files {
        for cut in 0..bytes.len() {
            let _ = io::read(&bytes[..cut], format);
            let mut flipped = bytes.clone();
            flipped[cut] ^= 0x5a;
            if let Ok(l) = io::read(&flipped[..], format) {
                assert!(l.points.positions.iter().all(|p| p.is_finite()));
            }
        }
    }
}
