//! Line plots of time histories as SVG and PNG (for `flexsens report`). Curves are told apart
//! by colour and dashes only: markers at regular intervals alias with oscillating histories.
//!
//! Text in the PNG files is drawn with the bundled DejaVu Sans font (`assets/fonts`, its
//! licence alongside), so no system font is needed; the SVG files name the font family and
//! leave the drawing of text to the viewer.

use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// DejaVu Sans (Bitstream Vera licence, `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// The font family every text uses.
const FAMILY: &str = "sans-serif";

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line {
    Solid,
    Dashed,
}

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub line: Line,
    /// Index into the palette.
    pub color: usize,
    /// Stroke width in pixels.
    pub width: u32,
}

impl Series {
    /// A solid line.
    pub fn solid(label: impl Into<String>, x: &[f64], y: &[f64], color: usize) -> Self {
        Self {
            label: label.into(),
            x: x.to_vec(),
            y: y.to_vec(),
            line: Line::Solid,
            color,
            width: 2,
        }
    }

    /// A dashed line.
    pub fn dashed(label: impl Into<String>, x: &[f64], y: &[f64], color: usize) -> Self {
        Self {
            line: Line::Dashed,
            ..Self::solid(label, x, y, color)
        }
    }
}

/// One set of axes.
#[derive(Clone, Debug)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    /// The quantity and its unit in brackets, e.g. `d(deflection)/dθ [1/deg]`; a power of ten
    /// that scales the values is put inside the brackets.
    pub y_label: String,
    pub series: Vec<Series>,
}

/// A figure: a title over one or more panels side by side.
#[derive(Clone, Debug)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
}

/// Width of one panel and height of a figure, pixels.
const PANEL_WIDTH: u32 = 760;
const HEIGHT: u32 = 560;

/// Colour-blind-safe palette (Okabe–Ito), black first.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(230, 159, 0),
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(240, 228, 66),
];

fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

impl Figure {
    /// Size in pixels.
    pub fn size(&self) -> (u32, u32) {
        // one panel gets room for a long title
        (
            (PANEL_WIDTH * self.panels.len().max(1) as u32).max(980),
            HEIGHT,
        )
    }

    /// The figure as an SVG document.
    pub fn svg(&self) -> Result<String, String> {
        register_fonts()?;
        let mut text = String::new();
        {
            let root = SVGBackend::with_string(&mut text, self.size()).into_drawing_area();
            self.draw(&root)?;
            root.present().map_err(|e| e.to_string())?;
        }
        Ok(text)
    }

    /// The figure as a PNG file.
    pub fn png(&self) -> Result<Vec<u8>, String> {
        register_fonts()?;
        let (w, h) = self.size();
        let mut rgb = vec![255u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
            self.draw(&root)?;
            root.present().map_err(|e| e.to_string())?;
        }
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, w, h);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut writer = enc.write_header().map_err(|e| e.to_string())?;
            writer.write_image_data(&rgb).map_err(|e| e.to_string())?;
        }
        Ok(bytes)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let body = root
            .titled(&self.title, (FAMILY, 22).into_font())
            .map_err(err)?;
        let areas = body.split_evenly((1, self.panels.len().max(1)));
        for (panel, area) in self.panels.iter().zip(&areas) {
            draw_panel(panel, area)?;
        }
        Ok(())
    }
}

/// Register the bundled font once per process.
fn register_fonts() -> Result<(), String> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            if register_font(FAMILY, style, FONT).is_err() {
                result = Err("the bundled font cannot be read".to_string());
            }
        }
    });
    result
}

/// Powers of ten as superscripts.
fn superscript(n: i32) -> String {
    n.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

/// The power of ten that brings values of magnitude up to `amax` near 1 (0 when they already
/// read well as plain numbers).
fn scale_exponent(amax: f64) -> i32 {
    if !(amax.is_finite() && amax > 0.0) {
        return 0;
    }
    let e = amax.log10().floor() as i32;
    if (-2..=3).contains(&e) { 0 } else { e }
}

/// `y_label` with `×10ⁿ` put in front of the unit in brackets.
fn scaled_label(label: &str, e: i32) -> String {
    if e == 0 {
        return label.to_string();
    }
    let factor = format!("×10{}", superscript(e));
    match label.rfind('[') {
        Some(i) if label.ends_with(']') => {
            let unit = &label[i + 1..label.len() - 1];
            if unit == "1" || unit == "–" || unit.is_empty() {
                format!("{}[{factor}]", &label[..i])
            } else {
                format!("{}[{factor} {unit}]", &label[..i])
            }
        }
        _ => format!("{label} [{factor}]"),
    }
}

/// Range of finite values with a margin; a unit range around a constant.
fn range(values: impl Iterator<Item = f64>, margin: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if lo > hi {
        return (-1.0, 1.0);
    }
    if hi - lo <= 1e-300_f64.max(1e-12 * hi.abs().max(lo.abs())) {
        let d = if hi == 0.0 { 1.0 } else { 0.1 * hi.abs() };
        return (lo - d, hi + d);
    }
    let m = margin * (hi - lo);
    (lo - m, hi + m)
}

fn draw_panel<DB: DrawingBackend>(
    panel: &Panel,
    area: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let amax = panel
        .series
        .iter()
        .flat_map(|s| s.y.iter())
        .filter(|v| v.is_finite())
        .fold(0.0_f64, |a, v| a.max(v.abs()));
    let e = scale_exponent(amax);
    let scale = 10f64.powi(-e);
    let (x0, x1) = range(panel.series.iter().flat_map(|s| s.x.iter().copied()), 0.0);
    let (y0, y1) = range(
        panel
            .series
            .iter()
            .flat_map(|s| s.y.iter().map(|v| v * scale)),
        0.05,
    );
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FAMILY, 19).into_font())
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(78)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(scaled_label(&panel.y_label, e))
        .label_style((FAMILY, 15).into_font())
        .axis_desc_style((FAMILY, 17).into_font())
        .x_labels(8)
        .y_labels(8)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(err)?;
    // zero line
    if y0 < 0.0 && y1 > 0.0 {
        chart
            .draw_series(LineSeries::new(
                vec![(x0, 0.0), (x1, 0.0)],
                RGBColor(150, 150, 150).stroke_width(1),
            ))
            .map_err(err)?;
    }
    for s in &panel.series {
        let c = color(s.color);
        let style = c.stroke_width(s.width);
        let points: Vec<(f64, f64)> =
            s.x.iter()
                .zip(&s.y)
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|(&x, &y)| (x, y * scale))
                .collect();
        let annotation = match s.line {
            Line::Solid => chart
                .draw_series(LineSeries::new(points.clone(), style))
                .map_err(err)?,
            Line::Dashed => chart
                .draw_series(DashedLineSeries::new(points.clone(), 9, 5, style))
                .map_err(err)?,
        };
        let (seg1, seg2) = match s.line {
            Line::Solid => (vec![(0, 0), (26, 0)], vec![(26, 0), (26, 0)]),
            Line::Dashed => (vec![(0, 0), (9, 0)], vec![(15, 0), (26, 0)]),
        };
        annotation.label(&s.label).legend(move |(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(seg1.clone(), style)
                + PathElement::new(seg2.clone(), style)
        });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FAMILY, 15).into_font())
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .draw()
        .map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_scale_by_powers_of_ten() {
        assert_eq!(scale_exponent(3.2e-5), -5);
        assert_eq!(scale_exponent(0.5), 0);
        assert_eq!(
            scaled_label("d(deflection)/dθ [1/deg]", -5),
            "d(deflection)/dθ [×10⁻⁵ 1/deg]"
        );
        assert_eq!(scaled_label("deflection [1]", -3), "deflection [×10⁻³]");
        assert_eq!(range([2.0, 2.0].into_iter(), 0.05), (1.8, 2.2));
    }

    #[test]
    fn figures_render_as_svg_and_png() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 1e-3).collect();
        let y: Vec<f64> = t.iter().map(|t| (300.0 * t).sin() * 1e-5).collect();
        let fig = Figure {
            title: "test".into(),
            panels: vec![Panel {
                title: "panel".into(),
                x_label: "time [s]".into(),
                y_label: "y [1/deg]".into(),
                series: vec![
                    Series::solid("a", &t, &y, 0),
                    Series::dashed("b", &t, &y, 1),
                ],
            }],
        };
        let svg = fig.svg().unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..50]);
        let png = fig.png().unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }
}
