//! Writes the geometrically exact reference history of the steel slider-crank (crank 0.152 m at
//! a constant 150 rad/s from t = 0, rod 0.304 m of 6 mm steel, slider 0.038 kg, no gravity):
//! the co-rotational beam of `reference/corotational.rs` with its converged discretisation
//! (32 elements, 1 µs), 0.1 s, every 0.1 ms.
//!
//! ```sh
//! cargo run --release -p flexsens-tests --example slider_crank_reference -- reference.csv
//! ```
//!
//! Columns: `t` (s), `mid_deflection` (the mid-length node's distance from the chord of the
//! rod's ends, over the rod's length, positive on the left of crank pin → slider), `slider_x`
//! (m). Used by `examples/time_to_accuracy/compare.py`.

use flexsens_tests::corotational::{self, Drive, SliderCrank};
use std::io::Write;

const T_END: f64 = 0.1;
const OUTPUT: f64 = 1e-4;

fn main() -> std::io::Result<()> {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: slider_crank_reference OUT.csv");
        std::process::exit(2);
    };
    let model = SliderCrank::steel(Drive::Constant { omega: 150.0 });
    let history =
        corotational::slider_crank(&model, &corotational::STEEL_DISCRETISATION, T_END, OUTPUT);
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
    writeln!(out, "t,mid_deflection,slider_x")?;
    for ((t, w), x) in history
        .t
        .iter()
        .zip(&history.mid_deflection)
        .zip(&history.slider_x)
    {
        writeln!(out, "{t:.6e},{:.12e},{x:.12e}", w / model.rod.length)?;
    }
    out.flush()
}
