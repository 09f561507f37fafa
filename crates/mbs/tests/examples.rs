//! The crate's example programs run as tests (their own checks assert).

#[path = "../examples/flexible_slider_crank.rs"]
mod flexible_slider_crank;

#[test]
fn flexible_slider_crank_example_runs() {
    flexible_slider_crank::main();
}
