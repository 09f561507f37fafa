//! Errors of the section layer.

use laminate::LaminateError;

/// Why a section mesh, its input text or its analysis was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionError {
    /// The mesh has no elements.
    #[error("the section mesh has no elements")]
    Empty,
    /// A node coordinate is NaN or infinite.
    #[error("node {node}: coordinates ({x2}, {x3}) are not finite")]
    NonFiniteNode { node: usize, x2: f64, x3: f64 },
    /// An element lists the wrong number of nodes for its kind.
    #[error("element {element}: a {kind} needs {expected} nodes, {got} were given")]
    WrongNodeCount {
        element: usize,
        kind: &'static str,
        expected: usize,
        got: usize,
    },
    /// An element refers to a node that does not exist.
    #[error("element {element}: node index {node} is out of range (the mesh has {count} nodes)")]
    NodeOutOfRange {
        element: usize,
        node: usize,
        count: usize,
    },
    /// An element lists the same node twice.
    #[error("element {element}: node {node} appears twice")]
    RepeatedNode { element: usize, node: usize },
    /// An element refers to a region (ply) that does not exist.
    #[error("element {element}: region index {region} is out of range ({count} regions)")]
    RegionOutOfRange {
        element: usize,
        region: usize,
        count: usize,
    },
    /// An element whose mapping is folded or whose corners run clockwise.
    #[error(
        "element {element} is inverted: Jacobian determinant {det_j:.3e} < 0 at an integration \
         point (corners must run counter-clockwise in the (x2, x3) plane)"
    )]
    InvertedElement { element: usize, det_j: f64 },
    /// An element with (nearly) zero area.
    #[error(
        "element {element} is degenerate: zero or nearly zero area (Jacobian determinant \
         {det_j:.3e} for a size of {size:.3e} m)"
    )]
    DegenerateElement {
        element: usize,
        det_j: f64,
        size: f64,
    },
    /// The mesh falls apart into pieces that share no node.
    #[error(
        "the section mesh is not connected: it has {parts} separate parts (element {element} \
         shares no node path with element 0)"
    )]
    Disconnected { parts: usize, element: usize },
    /// A region (ply, physical group) name that the caller did not define.
    #[error("unknown region (ply) name '{name}'{}", at_line(*line))]
    UnknownRegion { name: String, line: Option<usize> },
    /// A material name that the caller did not define.
    #[error("unknown material name '{name}'{}", at_line(*line))]
    UnknownMaterial { name: String, line: Option<usize> },
    /// Malformed mesh text.
    #[error("mesh text, line {line}: {message}")]
    Parse { line: usize, message: String },
    /// Invalid arguments to a mesh generator or to the design map.
    #[error("{0}")]
    InvalidInput(String),
    /// A ply angle or other region property is not finite.
    #[error("region '{region}': ply angle {angle} is not a finite number (radians)")]
    NonFiniteAngle { region: String, angle: f64 },
    /// The warping system could not be factorised (should not happen for a valid mesh).
    #[error("the warping system could not be factorised: {0}")]
    Factorisation(String),
    /// The warping system is too ill-conditioned for double precision: its condition number
    /// (of the diagonally scaled matrix; infinite when the factorisation failed) would cost
    /// the stiffness more than about 0.4 %. Walls very thin for the section's size do
    /// this: `thinness` is twice the area over the boundary length (the wall thickness of a
    /// thin wall), over the section's size (the diagonal of its bounding box).
    #[error(
        "the warping system is too ill-conditioned to solve in double precision (condition \
         number {}): the section's walls are about {thinness:.1e} of its size thick, and below \
         about 5e-4 a thin wall's in-plane bending is too soft against its stretching to \
         resolve (the error of the flatwise stiffness grows as the inverse fourth power of the \
         ratio). Model such a strip as a shell body, or give it a thicker section of equal \
         stiffness",
        condition_text(*condition)
    )]
    IllConditioned { condition: f64, thinness: f64 },
    /// The section compliance is singular or not finite.
    #[error("the section compliance matrix is singular or not finite")]
    SingularCompliance,
    /// A material rejected by the laminate layer.
    #[error(transparent)]
    Laminate(#[from] LaminateError),
}

fn at_line(line: Option<usize>) -> String {
    line.map(|l| format!(" (line {l})")).unwrap_or_default()
}

fn condition_text(c: f64) -> String {
    if c.is_finite() {
        format!("about {c:.1e}")
    } else {
        "beyond 1e16: the factorisation failed".into()
    }
}
