//! The crate's example programs run as tests (their own checks assert).

#[path = "../examples/composite_tube.rs"]
mod composite_tube;

#[test]
fn composite_tube_example_runs() {
    composite_tube::main().unwrap();
}
