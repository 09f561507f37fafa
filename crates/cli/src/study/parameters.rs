//! Design variables that set a model parameter directly: a rigid body's mass or principal
//! inertia, an actuator's gain — in the definitions (a study at another design) and in a built
//! model (in any scalar: a seeded dual for the sensitivities, a value for finite differences).

use super::*;
use crate::deck::mechanism::ForceDef;

/// Put the parameter a design variable's `target` sets (a rigid body's mass or principal
/// inertia, an actuator's gain) at `value` in `model`, the model of `mech`; other targets
/// leave it.
pub(crate) fn set_parameter<P: sens::Scalar>(
    model: &mut Model<P>,
    mech: &Mechanism,
    target: &Target,
    value: P,
) {
    if let Some((body, axis)) = target.rigid() {
        if let Body::Rigid(r) = model.body_mut(mech.bodies[body].id) {
            match axis {
                None => r.mass = value,
                Some(a) => r.inertia[(a, a)] = value,
            }
        }
    } else if let Some((force, gain)) = target.gain() {
        let id = (mech.forces.iter())
            .find(|(n, _)| n == force)
            .map(|(_, id)| *id)
            .expect("a validated gain names an actuator");
        let set = model.set_gain(id, gain, value);
        debug_assert!(set, "a validated gain is a PD law's");
    }
}

/// The definitions of `study` with the parameter `target` sets (a rigid body's mass or
/// principal inertia, an actuator's gain) at `value`; other targets leave them.
pub(super) fn move_definition(study: &mut Study, target: &Target, value: f64) {
    if let Some((body, axis)) = target.rigid() {
        let r = (study.rigid_bodies.iter_mut())
            .find(|r| r.name == body)
            .expect("a validated variable names a rigid body");
        match axis {
            None => r.mass = value,
            Some(a) => r.inertia[(a, a)] = value,
        }
    } else if let Some((force, gain)) = target.gain() {
        let law = study
            .forces
            .forces
            .iter_mut()
            .find_map(|(n, f, _)| match f {
                ForceDef::JointTorque { law, .. } | ForceDef::JointForce { law, .. }
                    if n == force =>
                {
                    Some(law)
                }
                _ => None,
            });
        if let Some(mbs::TorqueLaw::Pd { kp, kd, .. }) = law {
            *[kp, kd][gain] = value;
        }
    }
}
