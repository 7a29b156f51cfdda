//! Regressions from the robustness review: tool parameters that used to be silently ignored.

use glam::DVec3;
use sim_core::sampling::Shape;
use sim_core::tools::ToolError;
use sim_core::tools::emboss::{Emboss, GreyImage, Mapping, emboss};

use crate::common::fitted_object;

#[test]
fn emboss_rejects_non_finite_or_degenerate_mappings() {
    // A NaN origin or a zero axis made every uv() None: "0 points displaced", no error.
    let img = GreyImage::new(1, 1, vec![1.0]).unwrap();
    let mut o = fitted_object(Shape::Sphere { radius: 0.05 }, 500, 3);
    let before = o.positions.clone();
    for mapping in [
        Mapping::Spherical {
            center: DVec3::NAN,
            pole: DVec3::Z,
            reference: DVec3::X,
        },
        Mapping::Planar {
            origin: DVec3::ZERO,
            u_axis: DVec3::ZERO,
            v_axis: DVec3::Y,
        },
        Mapping::Cylindrical {
            origin: DVec3::ZERO,
            axis: DVec3::new(0.0, f64::INFINITY, 0.0),
            reference: DVec3::X,
        },
    ] {
        let op = Emboss {
            image: img.clone(),
            mapping,
            depth: 0.001,
        };
        let r = emboss(&op, &mut o.positions, &mut o.normals, &o.field, None);
        assert!(
            matches!(
                r,
                Err(ToolError::Param {
                    name: "mapping",
                    ..
                })
            ),
            "{mapping:?}: {r:?}"
        );
        assert_eq!(o.positions, before);
    }
}
