//! The explicit MPM step as named stages, each a pure function of what it reads.
//!
//! One USL step of size `Δt` from the particle state `(x, v, C, F, σ, history)` at `tⁿ`:
//!
//! | stage | reads | writes |
//! |---|---|---|
//! | 1. [`P2g::particle`] (per particle) | `x, v, C, F, σ, m, V⁰, half-width⁰` | its stencil of the step; node sums `m_i`, `(m v)_i`, `f_i` ([`NodeSums`]) |
//! | 2. [`momentum_update`] + [`NodeLaw::apply`] (per node) | node sums, `g`, `Δt`; walls, friction segments, obstacles at `tⁿ⁺¹` | `v_iⁿ = (m v)_i/m_i`, `v_i` and the node's [`NodeState`] |
//! | 3. [`G2p::particle`] (per particle) | its stencil, `v_i` (and `v_iⁿ` for FLIP), `v_p` | `v_p`, `C_p`, `x_p`; returns `L_p` |
//! | 4. [`particle_end`] (per particle) | `L_p`, `Δt`, `F`, `σ`, history, material; the walls | `F ← (I + Δt L) F`, `σ`, history; shallow wall crossings projected ([`EndOfStep::project`]); [`EndOfStep::flag`] |
//!
//! MUSL runs stage 3 without `L` ([`G2p::motion`]), maps the new particle momentum back with
//! the same stencils ([`momentum_to_grid`]), divides by the same nodal masses and enforces the
//! first projection's active set ([`NodeLaw::enforce`]), and takes `L` from that velocity
//! ([`G2p::velocity_gradient`]) before stage 4.
//!
//! Between the stages live only the grid fields above; nothing else carries over from one
//! step to the next: the state of a run is the particles plus the time and the step count.
//! A solver may fuse the loops of several stages (the CPU solver of `loam-explicit` does); a
//! reverse pass differentiates them one by one, and a step can record the branches they took
//! ([`StepRecord`]) so that the reverse pass replays them.
//!
//! Everything here is generic over the scalar type `T` (f32 for the GPU's CPU twin, f64, dual
//! numbers for derivatives); branches are taken on real parts.

mod g2p;
mod node;
mod p2g;
mod particle_end;
mod record;

pub use g2p::G2p;
pub use node::{NodeLaw, NodeState, momentum_update, on_a_face};
pub use p2g::{NodeSums, P2g, momentum_to_grid};
pub use particle_end::{EndOfStep, PROJECTION_DEPTH, particle_end, update_stress};
pub use record::{ParticleBranch, StepRecord};

#[cfg(test)]
mod tests;
