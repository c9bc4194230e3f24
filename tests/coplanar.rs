//! Coplanar surfaces and media (`scene::ties`): a box of medium resting on a floor, its
//! bottom face in the floor's plane. mediareg lets the floor win the tie, so the image
//! is that of the same box without its bottom face, closed by the floor: a scene
//! without a tie, which Mitsuba 3 renders unambiguously (`reference/medium_on_floor_open`).
//! Mitsuba 3 itself loses light along the contact (`reference/medium_on_floor`, its
//! render of the closed box); the power test shows the comparison sees that band.

mod common;

use common::{check_against_reference, check_edited_against_reference, load_seeded, root};
use mediareg::geometry::shape::Geometry;
use mediareg::scene::ties::Ties;

const CHUNKS: usize = 8;
const SPP: u32 = 64;

fn scene() -> std::path::PathBuf {
    root().join("mitsuba_scenes/medium_on_floor.xml")
}

#[test]
fn medium_box_resting_on_a_floor_renders_as_the_box_closed_by_the_floor() {
    let c = check_against_reference(
        "medium_on_floor_open",
        "medium_on_floor",
        &[],
        CHUNKS,
        SPP,
        11,
    );
    assert!(c.passed, "{c}");
}

/// The same with Mitsuba's `cube` (tested as a box by the accelerator, and otherwise a
/// convex medium whose rays would test only the box).
#[test]
fn medium_cube_resting_on_a_floor_renders_as_the_box_closed_by_the_floor() {
    let c = check_edited_against_reference(
        "medium_on_floor_open",
        &scene(),
        &root().join("mitsuba_scenes"),
        &[],
        &[
            (
                r#"<shape type="obj">
        <string name="filename" value="meshes/$box.obj"/>"#,
                r#"<shape type="cube">"#,
            ),
            (
                r#"<rotate y="1" angle="30"/>"#,
                r#"<scale value="0.5"/><rotate y="1" angle="30"/>"#,
            ),
        ],
        None,
        CHUNKS,
        SPP,
        12,
    );
    assert!(c.passed, "{c}");
}

/// Power: the render of the closed box is told from Mitsuba 3's, which loses the light
/// the floor reflects back into the medium along the contact.
#[test]
fn comparison_detects_the_light_lost_at_the_contact() {
    let c = check_against_reference("medium_on_floor", "medium_on_floor", &[], CHUNKS, SPP, 13);
    assert!(
        !c.passed,
        "the light lost at the contact went undetected: {c}"
    );
}

/// Only a scene with a contact pays for the check: with a gap under the box, or the
/// box sunk into the floor (which cuts its sides, in no face's plane), no boundary is
/// tied; resting on the floor, only the box's two bottom triangles are.
#[test]
fn only_a_boundary_with_a_surface_in_it_is_tied() {
    for floor_y in ["-0.51", "-0.49"] {
        let s = load_seeded(&scene(), &[("floor_y", floor_y)], 1, 0);
        assert!(
            s.tied_boundaries.is_empty(),
            "floor at {floor_y}: {:?}",
            s.tied_boundaries
        );
    }
    let s = load_seeded(&scene(), &[], 1, 0);
    assert_eq!(s.tied_boundaries.len(), 3);
    assert_eq!(s.tied_boundaries[1..], [Ties::None, Ties::None]);
    let Geometry::Mesh(m) = &s.geometries[0] else {
        panic!("the box is a mesh")
    };
    let bottom: Vec<u32> = (0..m.triangles.len() as u32)
        .filter(|&t| m.vertices(t).iter().all(|p| p.y < -0.49))
        .collect();
    assert_eq!(bottom.len(), 2);
    for t in 0..m.triangles.len() as u32 {
        assert_eq!(
            s.tied_boundaries[0].at(t),
            bottom.contains(&t),
            "triangle {t}"
        );
    }
}
