//! The checks of a material's keys that its declaration in
//! [`loam_core::constitutive::constants`] gives: which models take each key, whether it is
//! required, and its admissible range ("required for model …", "only used by …", "must be
//! positive …"). The rules between keys (ψ ≤ φ, κ < λ, …) are in [`super::check_material`].

use super::Checker;
use crate::schema::MaterialSpec;
use loam_core::constitutive::constants::{CONSTANTS, Constant, Need, ONE_OF};

/// Checks which keys a material's model takes and the range of each given key: "required for
/// model …", "only used by …", "give either … or …, not both", "must be …". Returns the keys
/// whose values are in range (cross-key rules only look at those).
pub(crate) fn check_keys(c: &mut Checker, path: &str, m: &MaterialSpec) -> Vec<&'static str> {
    let model = m.model;
    let mut sound = Vec::new();
    for key in CONSTANTS {
        let kpath = format!("{path}.{}", key.key);
        match (key.need(model), m.has(key.key)) {
            (None, true) => c.issue(kpath, key.misplaced(model)),
            (Some(Need::Required), false) => c.issue(
                kpath,
                format!("required for model \"{}\" ({})", model.name(), key.what),
            ),
            (Some(_), true) if in_range(c, &kpath, key, m) => sound.push(key.key),
            _ => {}
        }
    }
    for &(owner, first, second, what) in ONE_OF.iter().filter(|o| o.0 == model) {
        match (m.has(first), m.has(second)) {
            (false, false) => c.issue(
                format!("{path}.{first}"),
                format!("required for model \"{}\" ({what}", owner.name()),
            ),
            (true, true) => c.issue(
                format!("{path}.{second}"),
                format!(
                    "give either {first} or {second} for model \"{}\", not both",
                    owner.name()
                ),
            ),
            _ => {}
        }
    }
    sound
}

/// Whether the given key `key` of `m` is finite and in its declared range; records an issue
/// under `path` when not. A key without a range of its own (an enumeration, or a range set by
/// other keys: ψ ≤ φ, σ_t ≤ c cot φ) is left to the rules between keys.
fn in_range(c: &mut Checker, path: &str, key: &Constant, m: &MaterialSpec) -> bool {
    let (Some(range), Some(Some(x))) = (key.range, m.constant(key.key)) else {
        return true;
    };
    c.finite(path, x)
        && range
            .admit(x, key.unit)
            .map_err(|msg| c.issue(path, msg))
            .is_ok()
}
