//! Design variables: which ply angles and material stiffnesses move with which variable.

use nalgebra::Matrix6;

use crate::{SectionError, SectionMesh};

/// One design variable `b`: it moves the ply angle of each linked region by
/// `dθ_region/db = factor` (so `[θ/−θ]` is one variable linked to two plies with factors
/// `+1` and `−1`), the material stiffness `C̄` (material axes) of each region of
/// `materials` by `dC̄/db` (a material constant as a design variable), and the nodes of
/// `nodes` by their velocities `dX/db` (a ply thickness as a design variable: see
/// [`crate::GeneratedSection::node_velocities`]).
#[derive(Clone, Debug, PartialEq)]
pub struct DesignVariable {
    pub name: String,
    /// `(region index, dθ_region/db)`.
    pub links: Vec<(usize, f64)>,
    /// `(region index, dC̄_region/db)`.
    pub materials: Vec<(usize, Matrix6<f64>)>,
    /// `(region index, dρ_region/db)`: a material's density as a design variable.
    pub densities: Vec<(usize, f64)>,
    /// `(node index, dX_node/db)`: the section's geometry as a design variable (m per unit
    /// of `b`).
    pub nodes: Vec<(usize, [f64; 2])>,
}

impl DesignVariable {
    /// The `(node, dX/db)` links of the nodes that move, from one velocity per node.
    pub fn node_links(velocities: &[[f64; 2]]) -> Vec<(usize, [f64; 2])> {
        velocities
            .iter()
            .enumerate()
            .filter(|(_, v)| v[0] != 0.0 || v[1] != 0.0)
            .map(|(n, v)| (n, *v))
            .collect()
    }

    /// Whether the variable moves anything.
    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
            && self.materials.is_empty()
            && self.densities.is_empty()
            && self.nodes.is_empty()
    }
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

    /// The most variables [`crate::SectionAnalysis::sensitivities`] takes in one chunk: it
    /// skips those that move nothing and takes those that move nodes in chunks of their own,
    /// so a width beyond this number only adds tangents that stay zero.
    pub fn widest_chunk(&self) -> usize {
        let moves = self.variables.iter().filter(|v| !v.is_empty());
        let moving_nodes = moves.clone().filter(|v| !v.nodes.is_empty()).count();
        moving_nodes.max(moves.count() - moving_nodes)
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
                    materials: Vec::new(),
                    densities: Vec::new(),
                    nodes: Vec::new(),
                })
                .collect(),
        }
    }

    /// Add a variable linked to regions by index.
    pub fn with_variable(mut self, name: impl Into<String>, links: Vec<(usize, f64)>) -> Self {
        self.variables.push(DesignVariable {
            name: name.into(),
            links,
            materials: Vec::new(),
            densities: Vec::new(),
            nodes: Vec::new(),
        });
        self
    }

    /// Add a variable that moves the material stiffness of regions: `(region, dC̄/db)`.
    pub fn with_material_variable(
        mut self,
        name: impl Into<String>,
        materials: Vec<(usize, Matrix6<f64>)>,
    ) -> Self {
        self.variables.push(DesignVariable {
            name: name.into(),
            links: Vec::new(),
            materials,
            densities: Vec::new(),
            nodes: Vec::new(),
        });
        self
    }

    /// Add a variable that moves the section's nodes at the velocities `dX/db`, one per node
    /// of the mesh (e.g. [`crate::GeneratedSection::node_velocities`] of a ply thickness).
    pub fn with_geometry_variable(
        mut self,
        name: impl Into<String>,
        velocities: &[[f64; 2]],
    ) -> Self {
        self.variables.push(DesignVariable {
            name: name.into(),
            links: Vec::new(),
            materials: Vec::new(),
            densities: Vec::new(),
            nodes: DesignVariable::node_links(velocities),
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
            materials: Vec::new(),
            densities: Vec::new(),
            nodes: Vec::new(),
        });
        Ok(self)
    }

    /// Check that every link names an existing region with a finite factor.
    pub fn validate(&self, mesh: &SectionMesh) -> Result<(), SectionError> {
        for v in &self.variables {
            for &(n, dx) in &v.nodes {
                if n >= mesh.nodes.len() || !dx.iter().all(|x| x.is_finite()) {
                    return Err(SectionError::InvalidInput(format!(
                        "design variable '{}': node velocity of node {n} invalid (the mesh \
                         has {} nodes; velocities must be finite)",
                        v.name,
                        mesh.nodes.len()
                    )));
                }
            }
            for &(r, d) in &v.densities {
                if r >= mesh.regions.len() || !d.is_finite() {
                    return Err(SectionError::InvalidInput(format!(
                        "design variable '{}': density link to region {r} invalid (the mesh \
                         has {} regions; derivatives must be finite)",
                        v.name,
                        mesh.regions.len()
                    )));
                }
            }
            for (r, d) in &v.materials {
                if *r >= mesh.regions.len() || d.iter().any(|x| !x.is_finite()) {
                    return Err(SectionError::InvalidInput(format!(
                        "design variable '{}': material link to region {r} invalid (the mesh \
                         has {} regions; derivatives must be finite)",
                        v.name,
                        mesh.regions.len()
                    )));
                }
            }
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

    /// The mesh with design variable `var` moved by `step`: each linked region's ply angle
    /// changes by `factor · step` (radians) and each moving node by `dX/db · step` (exact for
    /// the generators, whose nodes are affine in the ply thicknesses). Material links are not
    /// applied (their constants belong to the caller).
    pub fn step(&self, mesh: &SectionMesh, var: usize, step: f64) -> SectionMesh {
        let mut m = mesh.clone();
        for &(r, factor) in &self.variables[var].links {
            m.regions[r].ply_angle += factor * step;
        }
        for &(n, dx) in &self.variables[var].nodes {
            m.nodes[n][0] += dx[0] * step;
            m.nodes[n][1] += dx[1] * step;
        }
        m
    }
}
