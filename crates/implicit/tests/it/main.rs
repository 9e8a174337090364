//! The integration tests of `implicit`, one binary (one link) for all of them.

mod coupled;
mod newmark;
mod rigid;
mod strength_reduction;

/// Central differences of the residual of `system` at `x`, column by column: calls
/// `visit(i, j, ∂R_i/∂x_j)` for every entry. Truncation O(ε²) against round-off
/// O(1e-16 |R| / ε): with unknowns (lengths) of ~1e-3 m, ε = 1e-8 m balances the two near
/// 1e-8 of the largest entry.
fn central_differences<const D: usize>(
    system: &loam_implicit::system::StepSystem<D>,
    materials: &loam_implicit::system::Materials,
    x: &[f64],
    mut visit: impl FnMut(usize, usize, f64),
) {
    let eps = 1e-8;
    for j in 0..x.len() {
        let mut xp = x.to_vec();
        xp[j] += eps;
        let rp = system.residual(&xp, materials).expect("residual");
        xp[j] -= 2.0 * eps;
        let rm = system.residual(&xp, materials).expect("residual");
        for i in 0..x.len() {
            visit(i, j, (rp[i] - rm[i]) / (2.0 * eps));
        }
    }
}
