//! Applied forces: point forces and torques (constant or tabulated in time), linear
//! spring–dampers and joint actuators (a torque about a joint's axis between its two bodies,
//! tabulated or a PD law tracking a motion). Gravity is a property of the [`crate::Model`].

use nalgebra::Vector3;

use crate::joint::TimeFunction;
use crate::marker::Marker;

/// Handle of a force element in a [`crate::Model`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ForceId(pub(crate) usize);

impl From<usize> for ForceId {
    /// The force at position `i` in the order added.
    fn from(i: usize) -> Self {
        ForceId(i)
    }
}

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
    /// An actuator: a torque `τ` (N·m) about the third axis `n` of marker `a`, `τ n` on `b`'s
    /// body (its node's rotation for an FE node) and `−τ n` on `a`'s, by the law `law`.
    JointTorque {
        a: Marker,
        b: Marker,
        law: TorqueLaw,
    },
    /// An actuator: a force `F` (N) along the third axis `n` of marker `a`, `F n` at `b`'s
    /// point and `−F n` at `a`'s, by the law `law` (a table of forces, or a PD law tracking the
    /// displacement `n · (x_B − x_A)` in m, as a distance driver measures it, with `kp` in N/m
    /// and `kd` in N·s/m).
    JointForce {
        a: Marker,
        b: Marker,
        law: TorqueLaw,
    },
}

/// The torque of a [`Force::JointTorque`] (or the force of a [`Force::JointForce`], N, its PD
/// law tracking a displacement in m).
#[derive(Clone, Debug, PartialEq)]
pub enum TorqueLaw {
    /// Piecewise linear in time through `(times[i], values[i])` (s, N·m), held constant
    /// outside; a single point is a constant torque.
    Table { times: Vec<f64>, values: Vec<f64> },
    /// A proportional–derivative law tracking the motion `f(t)` (rad) with the relative angle
    /// `θ` of the two markers (`b`'s first axis from `a`'s first, about `a`'s third, as an
    /// angle driver measures it): `τ = kp (f − θ) + kd (ḟ − θ̇)`, the angle error taken in
    /// `(−π, π]` (N·m/rad, N·m·s/rad).
    Pd {
        kp: f64,
        kd: f64,
        motion: TimeFunction,
    },
}

impl TorqueLaw {
    /// The tabulated torque at `t`.
    pub(crate) fn table_at(times: &[f64], values: &[f64], t: f64) -> f64 {
        let n = times.len();
        if t <= times[0] {
            return values[0];
        }
        if t >= times[n - 1] {
            return values[n - 1];
        }
        let i = times.partition_point(|&x| x <= t) - 1;
        let s = (t - times[i]) / (times[i + 1] - times[i]);
        values[i] * (1.0 - s) + values[i + 1] * s
    }
}

impl Force {
    /// The gains `[kp, kd]` of an actuator's PD law; `None` for the other forces.
    pub fn pd_gains(&self) -> Option<[f64; 2]> {
        match self {
            Force::JointTorque {
                law: TorqueLaw::Pd { kp, kd, .. },
                ..
            }
            | Force::JointForce {
                law: TorqueLaw::Pd { kp, kd, .. },
                ..
            } => Some([*kp, *kd]),
            _ => None,
        }
    }

    /// Times where the force's history has a kink (a table's points, the ends of a tracked
    /// motion's ramp).
    pub fn breakpoints(&self) -> Vec<f64> {
        match self {
            Force::PointForce {
                load: Load::Table { times, .. },
                ..
            }
            | Force::PointTorque {
                load: Load::Table { times, .. },
                ..
            }
            | Force::JointTorque {
                law: TorqueLaw::Table { times, .. },
                ..
            }
            | Force::JointForce {
                law: TorqueLaw::Table { times, .. },
                ..
            } => times.clone(),
            Force::JointTorque {
                law: TorqueLaw::Pd { motion, .. },
                ..
            }
            | Force::JointForce {
                law: TorqueLaw::Pd { motion, .. },
                ..
            } => motion.breakpoints(),
            _ => Vec::new(),
        }
    }

    pub(crate) fn markers(&self) -> Vec<&Marker> {
        match self {
            Force::PointForce { marker, .. } | Force::PointTorque { marker, .. } => vec![marker],
            Force::SpringDamper { a, b, .. }
            | Force::JointTorque { a, b, .. }
            | Force::JointForce { a, b, .. } => vec![a, b],
        }
    }
}
