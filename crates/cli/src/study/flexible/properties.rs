//! A flexible body's element properties and design: a beam's sections, a shell's laminates
//! and the regions of its mesh they laminate.

use super::*;

/// A shell body's properties (one laminate each, in order) and design from its laminates.
pub(super) fn shell(
    laminates: &[ShellLaminate],
    request: DesignRequest,
) -> (Properties<f64>, Design) {
    let props = Properties {
        sections: Vec::new(),
        laminates: laminates.iter().map(|l| l.stack.stiffness()).collect(),
    };
    (props, shell_design(laminates, request))
}

/// The elements of `mesh` laminated by each region of `laminates` get its laminate (an
/// element property), in the regions' order; a region that holds no element, or names one
/// that does not exist, is an error naming it.
pub(super) fn laminate_regions(
    src: &Source,
    laminates: &ShellLaminates,
    mesh: &mut fem::Mesh,
) -> Result<(), CliError> {
    let n = mesh.elements.len();
    for r in &laminates.regions {
        let fail =
            |m: String| CliError::Input(src.error(Some(r.span.clone()), Some(r.key.clone()), m));
        let held: Vec<usize> = match &r.elements {
            ElementSet::Elements(list) => {
                if let Some(&e) = list.iter().find(|&&e| e >= n) {
                    return Err(fail(format!(
                        "element {e} does not exist (the mesh has {n} elements)"
                    )));
                }
                list.clone()
            }
            ElementSet::Within(set) => {
                let nodes = node_set(src, set, &r.key, r.span.clone(), mesh)?;
                let mut inside = vec![false; mesh.nodes.len()];
                for k in nodes {
                    inside[k] = true;
                }
                (0..n)
                    .filter(|&e| mesh.elements[e].nodes().iter().all(|&k| inside[k]))
                    .collect()
            }
        };
        if held.is_empty() {
            return Err(fail(
                "no element of the body has all its nodes there (a region takes whole \
                 elements)"
                    .to_string(),
            ));
        }
        for e in held {
            if let fem::Element::Shell { property, .. } = &mut mesh.elements[e] {
                *property = r.laminate;
            }
        }
    }
    Ok(())
}

/// A beam body's properties from its sections (one per section, in order), and its design (the
/// sections' derivatives with respect to the variables `request` asks for); an error names the
/// key at fault.
pub(super) fn beam(
    sections: &[(String, SectionDef)],
    request: DesignRequest,
) -> Result<(Properties<f64>, Design), (&'static str, String)> {
    // one ply-angle variable per region of every section, each moving its own section
    let each_ply: Vec<(usize, String, usize)> = match request {
        DesignRequest::EachPly => sections
            .iter()
            .enumerate()
            .flat_map(|(s, (name, def))| {
                let prefix = if sections.len() > 1 {
                    format!("{name}.")
                } else {
                    String::new()
                };
                def.mesh
                    .regions
                    .iter()
                    .enumerate()
                    .map(move |(r, region)| (s, format!("{prefix}{}.angle", region.name), r))
            })
            .collect(),
        _ => Vec::new(),
    };
    let mut designs = Vec::with_capacity(sections.len());
    let mut props = Properties {
        sections: Vec::with_capacity(sections.len()),
        laminates: Vec::new(),
    };
    for (s, (name, section)) in sections.iter().enumerate() {
        let design = section_of_beam(name, section, request, |map| {
            for (owner, variable, r) in &each_ply {
                let links = if *owner == s { vec![(*r, 1.0)] } else { vec![] };
                *map = std::mem::take(map).with_variable(variable.clone(), links);
            }
        })?;
        props
            .sections
            .push(BeamSection::from_section(&design.sens.properties));
        designs.push(design);
    }
    let (names, values) = match request {
        DesignRequest::None => (Vec::new(), Vec::new()),
        DesignRequest::EachPly => (
            each_ply.iter().map(|(_, n, _)| n.clone()).collect(),
            vec![0.0; each_ply.len()],
        ),
        DesignRequest::Variables(vars) => (
            vars.iter().map(|v| v.name.clone()).collect(),
            vars.iter().map(|v| v.value).collect(),
        ),
    };
    let design = Design::Beam {
        sections: designs,
        names,
        values,
    };
    Ok((props, design))
}

/// The design of one section of a beam body: its values and derivatives with respect to the
/// variables `request` asks for (`each_ply` builds the design map of [`DesignRequest::EachPly`]).
fn section_of_beam(
    section_name: &str,
    section: &SectionDef,
    request: DesignRequest,
    each_ply: impl FnOnce(&mut DesignMap),
) -> Result<SectionDesign, (&'static str, String)> {
    let (map, materials) = match request {
        DesignRequest::None => (None, Vec::new()),
        DesignRequest::EachPly => {
            let mut map = DesignMap::new();
            each_ply(&mut map);
            let none = vec![Vec::new(); map.variables.len()];
            (Some(map), none)
        }
        DesignRequest::Variables(vars) => {
            let (map, materials) = section_design(section_name, section, vars)
                .map_err(|e| (".section", format!("section `{section_name}`: {e}")))?;
            (Some(map), materials)
        }
    };
    let s = match (&section.given, &map) {
        // given by its properties: only its own entries move it, linearly
        (Some(given), _) => given.properties().map(|properties| {
            let derivatives = match request {
                DesignRequest::Variables(vars) => vars
                    .iter()
                    .map(|v| match &v.target {
                        crate::deck::design::Target::SectionProperty { section, entry }
                            if section == section_name =>
                        {
                            given.derivative(*entry)
                        }
                        _ => Default::default(),
                    })
                    .collect(),
                DesignRequest::EachPly => map
                    .iter()
                    .flat_map(|m| &m.variables)
                    .map(|_| Default::default())
                    .collect(),
                DesignRequest::None => Vec::new(),
            };
            SectionSensitivities {
                properties,
                variables: map
                    .iter()
                    .flat_map(|m| &m.variables)
                    .map(|v| v.name.clone())
                    .collect(),
                derivatives,
            }
        }),
        (None, Some(map)) => section_derivatives(&section.mesh, map),
        (None, None) => section::analyse(&section.mesh).map(|p| SectionSensitivities {
            properties: p,
            ..Default::default()
        }),
    }
    .map_err(|e| ("", format!("section `{section_name}`: {e}")))?;
    Ok(SectionDesign::new(
        s,
        section.mesh.clone(),
        map.unwrap_or_default(),
        materials,
    ))
}
