//! Applied forces: point forces and torques (constant or tabulated in time) and linear
//! spring–dampers. Gravity is a property of the [`crate::Model`].

use nalgebra::Vector3;

use crate::marker::Marker;

/// Handle of a force element in a [`crate::Model`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ForceId(pub(crate) usize);

/// A vector load as a function of time.
#[derive(Clone, Debug, PartialEq)]
pub enum Load {
    Constant(Vector3<f64>),
    /// Piecewise-linear in time through `(times[i], values[i])`, held constant outside;
    /// `times` strictly increasing.
    Table {
        times: Vec<f64>,
        values: Vec<Vector3<f64>>,
    },
}

impl Load {
    pub fn at(&self, t: f64) -> Vector3<f64> {
        match self {
            Load::Constant(v) => *v,
            Load::Table { times, values } => {
                if t <= times[0] {
                    return values[0];
                }
                let n = times.len();
                if t >= times[n - 1] {
                    return values[n - 1];
                }
                let i = times.partition_point(|&x| x <= t) - 1;
                let s = (t - times[i]) / (times[i + 1] - times[i]);
                values[i] * (1.0 - s) + values[i + 1] * s
            }
        }
    }
}

/// Components in which a load is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadFrame {
    Global,
    /// The frame of the marker's body (the floating frame for a flexible body).
    Body,
}

/// A force element.
#[derive(Clone, Debug, PartialEq)]
pub enum Force {
    /// A force (N) applied at the marker point.
    PointForce {
        marker: Marker,
        load: Load,
        frame: LoadFrame,
    },
    /// A torque (N·m) applied to the marker's frame (a node's rotation for FE nodes).
    PointTorque {
        marker: Marker,
        load: Load,
        frame: LoadFrame,
    },
    /// A linear spring–damper between two marker points: tension
    /// `k (l − l0) + c l̇` (N, m, N/m, N·s/m).
    SpringDamper {
        a: Marker,
        b: Marker,
        stiffness: f64,
        damping: f64,
        free_length: f64,
    },
}

impl Force {
    /// Times where the force's history has a kink (a table's points).
    pub fn breakpoints(&self) -> &[f64] {
        match self {
            Force::PointForce {
                load: Load::Table { times, .. },
                ..
            }
            | Force::PointTorque {
                load: Load::Table { times, .. },
                ..
            } => times,
            _ => &[],
        }
    }

    pub(crate) fn markers(&self) -> Vec<&Marker> {
        match self {
            Force::PointForce { marker, .. } | Force::PointTorque { marker, .. } => vec![marker],
            Force::SpringDamper { a, b, .. } => vec![a, b],
        }
    }
}
