//! Design variables: which ply angles move with which variable.

use crate::{SectionError, SectionMesh};

/// One design variable `b`: it moves the ply angle of each linked region by
/// `dθ_region/db = factor` (so `[θ/−θ]` is one variable linked to two plies with factors
/// `+1` and `−1`).
#[derive(Clone, Debug, PartialEq)]
pub struct DesignVariable {
    pub name: String,
    /// `(region index, dθ_region/db)`.
    pub links: Vec<(usize, f64)>,
}

/// The design variables of a section analysis (ply angles, radians).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DesignMap {
    pub variables: Vec<DesignVariable>,
}

impl DesignMap {
    /// No variables.
    pub fn new() -> Self {
        Self::default()
    }

    /// One variable per region, each driving its own region's ply angle.
    pub fn each_region(mesh: &SectionMesh) -> Self {
        DesignMap {
            variables: mesh
                .regions
                .iter()
                .enumerate()
                .map(|(i, r)| DesignVariable {
                    name: r.name.clone(),
                    links: vec![(i, 1.0)],
                })
                .collect(),
        }
    }

    /// Add a variable linked to regions by index.
    pub fn with_variable(mut self, name: impl Into<String>, links: Vec<(usize, f64)>) -> Self {
        self.variables.push(DesignVariable {
            name: name.into(),
            links,
        });
        self
    }

    /// Add a variable linked to regions by name; unknown names are an error.
    pub fn with_named_variable(
        mut self,
        mesh: &SectionMesh,
        name: impl Into<String>,
        links: &[(&str, f64)],
    ) -> Result<Self, SectionError> {
        let links = links
            .iter()
            .map(|&(region, factor)| Ok((mesh.region_index(region)?, factor)))
            .collect::<Result<Vec<_>, SectionError>>()?;
        self.variables.push(DesignVariable {
            name: name.into(),
            links,
        });
        Ok(self)
    }

    /// Check that every link names an existing region with a finite factor.
    pub fn validate(&self, mesh: &SectionMesh) -> Result<(), SectionError> {
        for v in &self.variables {
            for &(r, factor) in &v.links {
                if r >= mesh.regions.len() {
                    return Err(SectionError::InvalidInput(format!(
                        "design variable '{}' links region index {r}, but the mesh has {} regions",
                        v.name,
                        mesh.regions.len()
                    )));
                }
                if !factor.is_finite() {
                    return Err(SectionError::InvalidInput(format!(
                        "design variable '{}': factor {factor} for region '{}' is not finite",
                        v.name, mesh.regions[r].name
                    )));
                }
            }
        }
        Ok(())
    }

    /// The mesh with design variable `var` moved by `step` (radians): each linked region's ply
    /// angle changes by `factor · step`. For finite-difference checks.
    pub fn step(&self, mesh: &SectionMesh, var: usize, step: f64) -> SectionMesh {
        let mut m = mesh.clone();
        for &(r, factor) in &self.variables[var].links {
            m.regions[r].ply_angle += factor * step;
        }
        m
    }
}
