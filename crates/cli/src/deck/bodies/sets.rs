//! Node sets on a body: couplings, supports, and the loads the deck's joints and forces put on
//! it.

use super::*;

/// A node set written as `nodes = [...]`, `plane = { x = … }` or `box = [[…], […]]` (one of
/// them) in the table `key` at `whole`.
pub(super) fn node_set(
    src: &Source,
    key: &str,
    whole: std::ops::Range<usize>,
    nodes: &Option<Spanned<Vec<i64>>>,
    plane: &Option<Spanned<RawPlane>>,
    inside: &Option<Spanned<[[f64; 3]; 2]>>,
) -> Result<NodeSet, DeckError> {
    let sk = |k: &str| format!("{key}.{k}");
    Ok(match (nodes, plane, inside) {
        (Some(n), None, None) => {
            let list = n.get_ref();
            if list.is_empty() || list.iter().any(|&x| x < 0) {
                return Err(src.error(
                    span(n),
                    Some(sk("nodes")),
                    "a list of node indices (from 0)",
                ));
            }
            NodeSet::Nodes(list.iter().map(|&x| x as usize).collect())
        }
        (None, Some(p), None) => {
            let pr = p.get_ref();
            let given: Vec<(usize, f64)> = [pr.x, pr.y, pr.z]
                .iter()
                .enumerate()
                .filter_map(|(a, v)| v.map(|v| (a, v)))
                .collect();
            match given.as_slice() {
                [(axis, value)] if value.is_finite() => NodeSet::Plane {
                    axis: *axis,
                    value: *value,
                },
                _ => {
                    return Err(src.error(
                        span(p),
                        Some(sk("plane")),
                        "one finite coordinate of a plane normal to a global axis, e.g. \
                         { x = 0.0 }",
                    ));
                }
            }
        }
        (None, None, Some(b)) => {
            let [lo, hi] = *b.get_ref();
            if (0..3).any(|a| !(lo[a].is_finite() && hi[a].is_finite() && lo[a] <= hi[a])) {
                return Err(src.error(
                    span(b),
                    Some(sk("box")),
                    "[[x0, y0, z0], [x1, y1, z1]] with finite corners, x0 ≤ x1, y0 ≤ y1, \
                     z0 ≤ z1",
                ));
            }
            NodeSet::Inside([lo, hi])
        }
        _ => {
            return Err(src.error(
                Some(whole),
                Some(key.to_string()),
                "give the nodes in one way: nodes = [...], plane = { x = … } or box = [[…], \
                 […]]",
            ));
        }
    })
}

/// Validate `[body.NAME.couplings]`.
pub(super) fn couplings(
    src: &Source,
    name: &str,
    raw: Option<&std::collections::BTreeMap<String, Spanned<RawCoupling>>>,
) -> Result<Vec<CouplingDef>, DeckError> {
    let mut out = Vec::new();
    for (cname, c) in raw.into_iter().flatten() {
        let key = format!("body.{name}.couplings.{cname}");
        let r = c.get_ref();
        let nodes = node_set(src, &key, c.span(), &r.nodes, &r.plane, &r.inside)?;
        let point = r
            .point
            .as_ref()
            .map(|p| vector(src, &format!("{key}.point"), p))
            .transpose()?;
        let rigid = match &r.kind {
            None => false,
            Some(kind) => match kind.get_ref().as_str() {
                "distributing" => false,
                "rigid" => true,
                other => {
                    return Err(src.error(Some(kind.span()), Some(format!("{key}.kind")), {
                        let [distributing, rigid] = super::super::keys::COUPLING_KIND.words else {
                            unreachable!("two kinds of coupling")
                        };
                        format!(
                            "unknown coupling kind `{other}`: expected \"{distributing}\" \
                                 (RBE3, the default) or \"{rigid}\" (RBE2)"
                        )
                    }));
                }
            },
        };
        out.push(CouplingDef {
            name: cname.clone(),
            nodes,
            point,
            rigid,
            key,
            span: c.span(),
        });
    }
    Ok(out)
}

/// The nodes among `interfaces` (joints and forces with `node = k`), each once.
pub(super) fn interface_nodes(interfaces: &[InterfaceDef]) -> Vec<usize> {
    let mut nodes: Vec<usize> = interfaces
        .iter()
        .filter_map(|i| match i.site {
            InterfaceSite::Node(k) => Some(k),
            InterfaceSite::Coupling(_) => None,
        })
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    nodes
}

/// Where a joint or force acts on a flexible body.
#[derive(Debug, Clone, PartialEq)]
pub enum InterfaceSite {
    Node(usize),
    Coupling(String),
}

/// The loads a joint or force puts on a flexible body: forces and moments along these
/// directions (global axes at the start, which are the mesh's).
#[derive(Debug, Clone, PartialEq)]
pub struct InterfaceDef {
    pub site: InterfaceSite,
    pub forces: Vec<Vector3<f64>>,
    pub moments: Vec<Vector3<f64>>,
}

/// The loads the deck's joints and forces put on body `name` (markers at a node or coupling
/// of it): a joint's reactions in the directions it constrains (a revolute joint takes no
/// moment about its axis, a spherical one no moment, a translational one no force along its
/// axis, a driver only its own direction), a point force or torque and a spring–damper in
/// every direction. Markers the mechanism validation will reject are left out.
pub fn interface_loads(deck: &RawDeck, name: &str) -> Vec<InterfaceDef> {
    let xyz = vec![Vector3::x(), Vector3::y(), Vector3::z()];
    // the two directions normal to a joint axis: the e1, e2 of its marker
    let normal_to = |a: Vector3<f64>| -> Vec<Vector3<f64>> {
        let a = a.try_normalize(0.0).unwrap_or(Vector3::z());
        let axes = mbs::Marker::ground(Vector3::zeros()).with_axis(a).axes;
        vec![axes.column(0).into_owned(), axes.column(1).into_owned()]
    };
    let site = |m: &Spanned<RawMarker>| -> Option<(InterfaceSite, Vector3<f64>)> {
        let m = m.get_ref();
        if m.body.as_ref()?.get_ref() != name {
            return None;
        }
        let axis = m
            .axis
            .as_ref()
            .map_or(Vector3::z(), |a| Vector3::from(*a.get_ref()));
        match (&m.node, &m.coupling) {
            (Some(n), None) if *n.get_ref() >= 0 => {
                Some((InterfaceSite::Node(*n.get_ref() as usize), axis))
            }
            (None, Some(c)) => Some((InterfaceSite::Coupling(c.get_ref().clone()), axis)),
            _ => None,
        }
    };
    let mut out = Vec::new();
    for j in deck.joint.values() {
        let j = j.get_ref();
        let kind = j.kind.as_ref().map_or("", |k| k.get_ref().as_str());
        for m in [&j.a, &j.b].into_iter().flatten() {
            let Some((site, axis)) = site(m) else {
                continue;
            };
            let (forces, moments) = match kind {
                "spherical" => (xyz.clone(), vec![]),
                "revolute" | "universal" => (xyz.clone(), normal_to(axis)),
                "cylindrical" => (normal_to(axis), normal_to(axis)),
                "translational" => (normal_to(axis), xyz.clone()),
                "angle-driver" => (vec![], vec![axis]),
                "distance-driver" => (xyz.clone(), vec![]),
                _ => (xyz.clone(), xyz.clone()),
            };
            out.push(InterfaceDef {
                site,
                forces,
                moments,
            });
        }
    }
    for f in deck.force.values() {
        let f = f.get_ref();
        let kind = f.kind.as_ref().map_or("", |k| k.get_ref().as_str());
        for m in [&f.at, &f.a, &f.b].into_iter().flatten() {
            let Some((site, _)) = site(m) else {
                continue;
            };
            let (forces, moments) = match kind {
                "point-torque" => (vec![], xyz.clone()),
                _ => (xyz.clone(), vec![]),
            };
            out.push(InterfaceDef {
                site,
                forces,
                moments,
            });
        }
    }
    out
}

/// The dof names of a support's `fix` list, in the order of the nodal dof.
pub(super) const DOF_NAMES: [&str; 6] = ["ux", "uy", "uz", "rx", "ry", "rz"];

/// Validate `supports = [ … ]` of body `name`.
pub(super) fn supports(
    src: &Source,
    name: &str,
    raw: &[Spanned<RawSupport>],
) -> Result<Vec<SupportDef>, DeckError> {
    let mut out = Vec::new();
    for (i, s) in raw.iter().enumerate() {
        let key = format!("body.{name}.supports[{i}]");
        let sk = |k: &str| format!("{key}.{k}");
        let r = s.get_ref();
        let nodes = node_set(src, &key, s.span(), &r.nodes, &r.plane, &r.inside)?;
        let fix = required(
            src,
            span(s),
            &sk("fix"),
            &r.fix,
            "fix (\"clamped\", \"pinned\" or a list of dof)",
        )?;
        let bad_fix = || {
            src.error(
                span(fix),
                Some(sk("fix")),
                format!(
                    "expected \"clamped\", \"pinned\" or a list of dof names from {}",
                    DOF_NAMES.join(", ")
                ),
            )
        };
        let dofs: Vec<usize> = match fix.get_ref() {
            toml::Value::String(w) if w == "clamped" => (0..6).collect(),
            toml::Value::String(w) if w == "pinned" => (0..3).collect(),
            toml::Value::Array(list) if !list.is_empty() => {
                let mut d = Vec::new();
                for v in list {
                    let n = v
                        .as_str()
                        .and_then(|w| DOF_NAMES.iter().position(|x| *x == w));
                    match n {
                        Some(n) if !d.contains(&n) => d.push(n),
                        _ => return Err(bad_fix()),
                    }
                }
                d
            }
            _ => return Err(bad_fix()),
        };
        out.push(SupportDef {
            nodes,
            dofs,
            key,
            span: s.span(),
        });
    }
    Ok(out)
}
