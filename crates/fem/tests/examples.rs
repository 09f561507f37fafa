//! The crate's example programs run as tests (their own checks assert).

#[path = "../examples/plate_modes.rs"]
mod plate_modes;

#[test]
fn plate_modes_example_runs() {
    plate_modes::main().unwrap();
}
