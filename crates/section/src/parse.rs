//! Mesh text parsers.
use crate::{SectionError, SectionMesh, WallFrame};
use laminate::OrthotropicMaterial;

/// Properties of a named region (a Gmsh physical group).
#[derive(Clone, Debug, PartialEq)]
pub struct RegionSpec {
    pub name: String,
    pub material: OrthotropicMaterial,
    pub ply_angle: f64,
    pub frame: WallFrame,
}

pub fn parse_gmsh(_text: &str, _regions: &[RegionSpec]) -> Result<SectionMesh, SectionError> {
    Err(SectionError::InvalidInput("not implemented yet".into()))
}
pub fn parse_simple(
    _text: &str,
    _materials: &[(&str, OrthotropicMaterial)],
) -> Result<SectionMesh, SectionError> {
    Err(SectionError::InvalidInput("not implemented yet".into()))
}
