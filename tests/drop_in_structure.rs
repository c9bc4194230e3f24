//! Drop-in structure of published scenes (issue 30, part C): geometry instancing
//! (`shapegroup` + `instance`), objects referenced before they are declared, several or
//! no sensors, integrators rendered by one of mediareg's, media nested without a name,
//! and unread properties in files older than 2.0.

mod common;

use common::check_against_reference;

const CHUNKS: usize = 8;
const SPP: u32 = 64;

/// Three instances of a two-shape group (a cube and a sphere), referred to before the
/// group is declared, against Mitsuba 3 (`reference/instances`, 16384 spp).
#[test]
fn instances_match_mitsuba() {
    let c = check_against_reference("instances", "instances", &[], CHUNKS, SPP, 11);
    assert!(c.passed, "{c}");
}

/// Power: the second instance moved by 0.02 (of a 8-unit floor; about a third of a pixel)
/// is detected.
#[test]
fn instances_comparison_detects_an_instance_moved() {
    let c = check_against_reference(
        "instances",
        "instances",
        &[("tree2_x", "0.12")],
        CHUNKS,
        SPP,
        12,
    );
    assert!(!c.passed, "an instance moved by 0.02 went undetected: {c}");
}
