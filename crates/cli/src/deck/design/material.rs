//! Material design variables: the ten constants of an orthotropic material, the laws that
//! move them, and the `[design.*]` tables of kind `"material"`.

use super::*;

/// A material's nine elastic constants (`OrthotropicMaterial::constants`) and its density.
pub fn material_constants(m: &laminate::OrthotropicMaterial) -> [f64; 10] {
    let c = m.constants();
    [
        c[0],
        c[1],
        c[2],
        c[3],
        c[4],
        c[5],
        c[6],
        c[7],
        c[8],
        m.density(),
    ]
}

/// How a material design variable moves its material's ten constants
/// ([`material_constants`] order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MaterialLaw {
    /// `c(b) = c0 + dc (b − b0)`: an orthotropic material's constant, or a density.
    Linear([f64; 10]),
    /// An isotropic material's modulus `E` (`E1 = E2 = E3`) at fixed ν; the shear moduli
    /// follow, `G = E/(2(1 + ν))`.
    IsotropicModulus,
    /// An isotropic material's Poisson ratio ν (`nu12 = nu13 = nu23`) at fixed `E`; the shear
    /// moduli follow, `G = E/(2(1 + ν))` (not linear in ν: the constants at another design are
    /// made exactly, and the tangent is taken where the material is).
    IsotropicPoisson,
}

impl MaterialLaw {
    /// `dc/db` at the constants `c`.
    pub fn tangent(&self, c: &[f64; 10]) -> [f64; 10] {
        let (e, nu) = (c[0], c[6]);
        match self {
            MaterialLaw::Linear(dc) => *dc,
            MaterialLaw::IsotropicModulus => {
                let g = 1.0 / (2.0 * (1.0 + nu));
                [1.0, 1.0, 1.0, g, g, g, 0.0, 0.0, 0.0, 0.0]
            }
            MaterialLaw::IsotropicPoisson => {
                let g = -e / (2.0 * (1.0 + nu) * (1.0 + nu));
                [0.0, 0.0, 0.0, g, g, g, 1.0, 1.0, 1.0, 0.0]
            }
        }
    }

    /// The constants `c0` moved by each `(law, b − b0)`, exactly: the moduli, Poisson ratios
    /// and densities by their steps, then an isotropic material's shear moduli from its `E`
    /// and ν.
    pub fn moved<'a>(
        c0: [f64; 10],
        moves: impl IntoIterator<Item = (&'a MaterialLaw, f64)>,
    ) -> [f64; 10] {
        let mut c = c0;
        let mut isotropic = false;
        for (law, step) in moves {
            match law {
                MaterialLaw::Linear(dc) => {
                    for (ci, d) in c.iter_mut().zip(dc) {
                        *ci += d * step;
                    }
                }
                MaterialLaw::IsotropicModulus => {
                    isotropic = true;
                    c[..3].iter_mut().for_each(|x| *x += step);
                }
                MaterialLaw::IsotropicPoisson => {
                    isotropic = true;
                    c[6..9].iter_mut().for_each(|x| *x += step);
                }
            }
        }
        if isotropic {
            let g = c[0] / (2.0 * (1.0 + c[6]));
            c[3..6].iter_mut().for_each(|x| *x = g);
        }
        c
    }
}

/// The elastic part of [`material_constants`].
pub fn elastic(c: &[f64; 10]) -> [f64; 9] {
    [c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8]]
}

/// The material with the constants `c` ([`material_constants`] order).
pub fn with_material_constants(
    m: &laminate::OrthotropicMaterial,
    c: &[f64; 10],
) -> Result<laminate::OrthotropicMaterial, LaminateError> {
    m.with_constants(elastic(c))?.with_density(c[9])
}

/// The elastic constants a material variable may move: deck name, index in
/// `OrthotropicMaterial::constants`, unit.
pub(super) const ORTHOTROPIC: [(&str, usize, &str); 9] = [
    ("E1", 0, "Pa"),
    ("E2", 1, "Pa"),
    ("E3", 2, "Pa"),
    ("G12", 3, "Pa"),
    ("G13", 4, "Pa"),
    ("G23", 5, "Pa"),
    ("nu12", 6, "1"),
    ("nu13", 7, "1"),
    ("nu23", 8, "1"),
];

/// An elastic constant of a material as a design variable.
pub(super) fn material_variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
    model: &LaminateModel,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let mat = required(
        src,
        span(d),
        &k("material"),
        &rd.material,
        "material (a [material.*] name)",
    )?;
    let Some(m) = model.materials.get(mat.get_ref()) else {
        let known: Vec<&str> = model.materials.keys().map(String::as_str).collect();
        return Err(src.error(
            span(mat),
            Some(k("material")),
            format!(
                "undefined material `{}`{}",
                mat.get_ref(),
                suggestion(mat.get_ref(), &known)
            ),
        ));
    };
    let isotropic = raw.material[mat.get_ref()].get_ref().e.is_some();
    let c = required(src, span(d), &k("constant"), &rd.constant, "constant")?;
    let c0 = m.constants();
    let (constant, law, value, unit) = match (isotropic, c.get_ref().as_str()) {
        (true, "E") => ("E", MaterialLaw::IsotropicModulus, c0[0], "Pa"),
        (true, "nu") => ("nu", MaterialLaw::IsotropicPoisson, c0[6], "1"),
        (false, other) if ORTHOTROPIC.iter().any(|(n, _, _)| *n == other) => {
            let &(n, i, unit) = ORTHOTROPIC
                .iter()
                .find(|(n, _, _)| *n == other)
                .expect("matched");
            let mut dc = [0.0; 10];
            dc[i] = 1.0;
            (n, MaterialLaw::Linear(dc), c0[i], unit)
        }
        (_, "density") => {
            let mut dc = [0.0; 10];
            dc[9] = 1.0;
            ("density", MaterialLaw::Linear(dc), m.density(), "kg/m^3")
        }
        (true, other) => {
            return Err(src.error(
                span(c),
                Some(k("constant")),
                format!(
                    "`{other}`: material `{}` is isotropic: its design constants are \"E\", \
                     \"nu\" and \"density\" (or give the material's nine orthotropic constants)",
                    mat.get_ref()
                ),
            ));
        }
        (false, other) => {
            let names: Vec<&str> = ORTHOTROPIC.iter().map(|(n, _, _)| *n).collect();
            return Err(src.error(
                span(c),
                Some(k("constant")),
                format!(
                    "unknown constant `{other}`: expected one of {}{}",
                    names.join(", "),
                    suggestion(other, &names)
                ),
            ));
        }
    };
    Ok(DesignVariable {
        name: name.to_string(),
        target: Target::Material {
            material: mat.get_ref().clone(),
            constant,
            law,
        },
        value,
        unit,
    })
}
