//! Shared set-up of the granular-collapse cases ([`crate::bui`] and [`crate::runout`]).
//!
//! A rectangular column of cohesionless Drucker–Prager material, `L₀` long and `H₀` high,
//! stands at rest against the left wall of a plane-strain box and collapses under gravity when
//! its right side is released at `t = 0`. The left wall is a frictionless bilateral slip wall,
//! i.e. a symmetry plane: the column is the right half of a column `2L₀` wide, as in the
//! channel experiments of Lube et al. (2005) and Lajeunesse et al. (2005), where the column is
//! released from a back wall. The floor carries Coulomb friction `μ` over its whole length
//! (one `[[friction]]` segment); the right wall and the lid are never reached (checked).
//!
//! Quadratic B-splines, APIC, MUSL, 2 × 2 particles per cell, adaptive `Δt` (Courant number
//! 0.4 on the elastic P-wave speed). Each case's scene file (`verification/scenes/`) holds
//! the reference set-up; [`Collapse::scene`] sets the box, column, cell size and material of a
//! run on it, and `loam-scene` builds it.
//!
//! **Initial stress.** The column starts in the at-rest state, `σ_yy = −ρ₀ g (H₀ − y)`,
//! `σ_xx = σ_zz = K₀ σ_yy` with Jaky's `K₀ = 1 − sin φ` (the scene's `geostatic` initial
//! stress, depths measured from `y = H₀`), as a column built in a box and held by a gate. A stress-free start with gravity switched on at `t = 0`
//! would load the column dynamically and, with ν = 0.3, towards the elastic
//! `K₀ = ν/(1 − ν) = 0.43`, which lies outside the Drucker–Prager cone for any φ below about
//! 34° (`(1 − K₀)/√3 > α (1 + 2K₀)`): the whole column would yield before the collapse starts.
//! (The runout hardly notices: 0.4460 m from a stress-free start against 0.4462 m for the Bui
//! case at h = 5 mm; the at-rest start is kept because it is the state of the experiments.)
//!
//! **The floor.** A separable slip wall under one Coulomb segment, as the scene files require:
//! the unilateral nodal law of [`loam_core::contact`] on the floor nodes and the ghost nodes
//! below them. A nodal condition does not by itself keep particle *centres* above the floor: a
//! particle at height `y_p` still interpolates the downward velocity of the first interior
//! node (weight 1/8 at `y_p = 0` for quadratic B-splines), so where a flowing layer thins to
//! less than half a particle spacing (the front of the collapse) a centre can end a step a
//! fraction of a millimetre below `y = 0` (up to 0.16 particle spacings measured). The
//! explicit solver puts such shallow crossings of a unilateral wall back onto the face
//! (`loam_explicit::Solver`, projection of the centre and of its velocity into the wall);
//! a centre more than half a cell below the floor would stop the run.
//!
//! **Deposit measures** (from the particle state):
//!
//! - the *thickness profile* [`thickness_profile`]: per column of width `w` (the cell size)
//!   from the wall, the solid-equivalent thickness `Σ m_p / (ρ₀ w)`, the height the material
//!   of that column would have at its initial density, averaged over a window of [`WINDOW`]
//!   (20 mm). It is exactly `H₀` over the initial column, does not depend on how the particles
//!   are arranged, and does not count as height the dilation of particles that went through
//!   the tension cutoff;
//! - the *toe* [`toe`]: starting from the wall, the columns whose averaged thickness is at
//!   least `t_min` = [`MIN_THICKNESS`] (4 mm) and that are contiguous; the toe is the right
//!   edge `x_p + d_p/2` of the rightmost particle in them. The first column below `t_min` ends
//!   the deposit, so grains flung ahead of the front do not count, and neither does a film
//!   thinner than `t_min`. The film matters: a rate-independent continuum on a Coulomb floor
//!   has no minimum flowing thickness (a real granular layer stops below a few grain
//!   diameters, Pouliquen's `h_stop`), so its front thins into a tongue one particle thick
//!   whose length grows as the grid is refined (Bui case, toe of any contiguous material,
//!   [`Sample::film_toe`]: 0.40, 0.45, 0.57 m at h = 10, 5, 2.5 mm). `t_min` is a few grain
//!   diameters;
//! - the *height at the wall* [`wall_height`]: the top `y_p + d_p/2` of the highest particle in
//!   the first column `0 ≤ x < w` (exactly `H₀` at `t = 0`).
//!
//! **At rest.** A pile is at rest when its kinetic energy `K` is negligible against the
//! potential energy released, `ΔE_p = E_p(0) − E_p(t)`, and its toe has stopped moving
//! ([`Outcome::rest_ratio`], [`Outcome::late_toe_motion`]).

use crate::device::ExplicitRun;
use crate::{Device, Series, VerifyError, scenes, write_csv};
use loam_core::Particles;
use loam_explicit::Config;
use loam_scene::{BodyShape, InitialStressSpec, Scene};
use std::path::Path;

/// Deposit threshold `t_min` of [`toe`] (m): 4 mm, about three diameters of the 1–1.5 mm
/// aluminium rods of Bui et al. (2008), and a few diameters of the sands and beads (fractions
/// of a millimetre to a few millimetres) of Lube et al. and Lajeunesse et al. (2005): the order
/// of the thickness below which a granular layer stops flowing.
pub const MIN_THICKNESS: f64 = 4e-3;

/// Averaging window of the thickness profile that [`toe`] thresholds (m): 20 mm, four to
/// eight particle spacings on the grids used. A single column of one cell holds two or four
/// particle columns, and once the material has sheared that count varies from column to
/// column by one or two (±25–50 % of the thickness), which would let one sparse column cut the
/// deposit short; 20 mm averages that out while staying well below the deposit's length.
pub const WINDOW: f64 = 0.02;

/// Gravitational acceleration (m/s²).
pub const G: f64 = 9.81;

/// Cohesionless Drucker–Prager material and floor friction of a collapse.
#[derive(Clone, Copy, Debug)]
pub struct Granular {
    /// Density `ρ₀` (kg/m³).
    pub density: f64,
    /// Young's modulus `E` (Pa).
    pub young: f64,
    /// Poisson's ratio `ν`.
    pub poisson: f64,
    /// Friction angle `φ` (degrees).
    pub friction_deg: f64,
    /// Dilation angle `ψ` (degrees).
    pub dilation_deg: f64,
    /// Coulomb coefficient `μ` of the floor.
    pub floor_mu: f64,
}

impl Granular {
    /// The material and floor of a collapse scene: its first material (Drucker–Prager) and the
    /// coefficient of its first friction segment (the floor).
    pub fn from_scene(scene: &Scene) -> Self {
        let m = &scene.materials[0];
        Self {
            density: m.density,
            young: m.youngs_modulus.unwrap_or(f64::NAN),
            poisson: m.poisson_ratio.unwrap_or(f64::NAN),
            friction_deg: m.friction_angle.unwrap_or(f64::NAN),
            dilation_deg: m.dilation_angle.unwrap_or(0.0),
            floor_mu: scene.friction[0].mu,
        }
    }

    /// P-wave modulus `M = E(1 − ν)/((1 + ν)(1 − 2ν))` (Pa).
    pub fn p_wave_modulus(&self) -> f64 {
        let nu = self.poisson;
        self.young * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// Elastic compression at the base of a column of height `h0`, `ρ₀ g H₀ / M`.
    pub fn elastic_strain(&self, h0: f64) -> f64 {
        self.density * G * h0 / self.p_wave_modulus()
    }
}

/// One collapse: column, box, discretisation and duration.
#[derive(Clone, Copy, Debug)]
pub struct Collapse {
    /// The stem of the case's scene file in `verification/scenes/` ([`Collapse::scene`]).
    pub scene: &'static str,
    /// Material and floor.
    pub material: Granular,
    /// Initial column length `L₀` (m), against the wall at `x = 0`.
    pub l0: f64,
    /// Initial column height `H₀` (m).
    pub h0: f64,
    /// Box length (m), a whole number of cells.
    pub length: f64,
    /// Box height (m), a whole number of cells.
    pub height: f64,
    /// Cell size `h` (m); `L₀` and `H₀` must be whole numbers of particle spacings.
    pub h: f64,
    /// Particles per cell per axis.
    pub ppc: usize,
    /// Simulated duration (s).
    pub end_time: f64,
}

impl Collapse {
    /// Particle spacing `d_p = h / ppc`.
    pub fn spacing(&self) -> f64 {
        self.h / self.ppc as f64
    }

    /// Aspect ratio `a = H₀/L₀`.
    pub fn aspect(&self) -> f64 {
        self.h0 / self.l0
    }
}

/// Number of lengths `step` in `len` (a whole number of them).
fn count(len: f64, step: f64) -> usize {
    let n = (len / step).round();
    debug_assert!(
        (n * step - len).abs() < 1e-9 * len,
        "{len} is not a multiple of {step}"
    );
    n as usize
}

impl Collapse {
    /// The scene of the collapse: the case's scene file with this box, cell size, particles
    /// per cell, column (its at-rest stress measured from its top, `y = H₀`), material, floor
    /// friction and end time.
    pub fn scene(&self) -> Scene {
        let mut scene = scenes::scene(self.scene);
        scene.grid.cell_size = self.h;
        scene.grid.hi = vec![self.length, self.height];
        let m = &mut scene.materials[0];
        m.density = self.material.density;
        m.youngs_modulus = Some(self.material.young);
        m.poisson_ratio = Some(self.material.poisson);
        m.friction_angle = Some(self.material.friction_deg);
        m.dilation_angle = Some(self.material.dilation_deg);
        scene.friction[0].mu = self.material.floor_mu;
        let body = &mut scene.bodies[0];
        body.shape = BodyShape::Box {
            lo: vec![0.0, 0.0],
            hi: vec![self.l0, self.h0],
        };
        body.particles_per_cell = self.ppc as u32;
        body.initial_stress = Some(InitialStressSpec::Geostatic {
            k0: None,
            surface: Some(self.h0),
        });
        scene.solver.end_time = Some(self.end_time);
        scene
    }
}

/// Builds the box and the column (at rest, in the at-rest stress state) of
/// [`Collapse::scene`].
pub fn build(c: &Collapse) -> (Config<f64, 2>, Particles<f64, 2>) {
    let built = scenes::build::<2>(&c.scene());
    let config = built
        .explicit_config()
        .expect("a collapse is an explicit scene");
    (config, built.particles)
}

/// The column of width `width` from the wall that holds `x` (the last one for `x` beyond).
fn column_of(x: f64, width: f64, n: usize) -> usize {
    ((x / width).floor().max(0.0) as usize).min(n - 1)
}

/// Solid-equivalent thickness per column `[j w, (j + 1) w)` from the wall up to
/// `x = length`, as `(column centre x_j, thickness)`: the mass of the particles in the window
/// `[x_j − window/2, x_j + window/2]` (cut at the wall) over `ρ₀` times the window's length.
/// With `window = w` this is `Σ m_p / (ρ₀ w)` over the column.
pub fn thickness_profile(
    p: &Particles<f64, 2>,
    width: f64,
    length: f64,
    density: f64,
    window: f64,
) -> Vec<(f64, f64)> {
    let mut xm: Vec<(f64, f64)> = p.x.iter().zip(&p.mass).map(|(x, &m)| (x[0], m)).collect();
    xm.sort_by(|a, b| a.0.total_cmp(&b.0));
    // prefix[k]: mass of the k leftmost particles.
    let mut prefix = vec![0.0];
    for &(_, m) in &xm {
        prefix.push(prefix[prefix.len() - 1] + m);
    }
    let below = |x: f64| xm.partition_point(|&(xp, _)| xp < x);
    (0..count(length, width))
        .map(|j| {
            let xc = (j as f64 + 0.5) * width;
            let (lo, hi) = ((xc - 0.5 * window).max(0.0), xc + 0.5 * window);
            let mass = prefix[below(hi)] - prefix[below(lo)];
            (xc, mass / (density * (hi - lo)))
        })
        .collect()
}

/// The toe of the deposit: the right edge (`x_p + spacing/2`) of the rightmost particle in the
/// columns of width `width` that, contiguous from the wall, hold a solid-equivalent thickness
/// (averaged over `window`, see [`thickness_profile`]) of at least `min_thickness`; see the
/// [module](self) docs.
pub fn toe(
    p: &Particles<f64, 2>,
    width: f64,
    length: f64,
    density: f64,
    window: f64,
    min_thickness: f64,
    spacing: f64,
) -> f64 {
    let profile = thickness_profile(p, width, length, density, window);
    let end = profile
        .iter()
        .position(|&(_, t)| t < min_thickness)
        .unwrap_or(profile.len());
    let limit = end as f64 * width;
    p.x.iter()
        .map(|x| x[0])
        .filter(|&x| x < limit)
        .fold(0.0, f64::max)
        + 0.5 * spacing
}

/// The height of the deposit at the wall: the top (`y_p + spacing/2`) of the highest particle
/// with `x_p < width`.
pub fn wall_height(p: &Particles<f64, 2>, width: f64, spacing: f64) -> f64 {
    p.x.iter()
        .filter(|x| x[0] < width)
        .map(|x| x[1])
        .fold(0.0, f64::max)
        + 0.5 * spacing
}

/// The free surface: per column of width `width`, the top (`y_p + spacing/2`) of the highest
/// particle, as `(column centre, height)`; empty columns are left out.
pub fn surface(p: &Particles<f64, 2>, width: f64, length: f64, spacing: f64) -> Vec<(f64, f64)> {
    let n = count(length, width);
    let mut top = vec![f64::NEG_INFINITY; n];
    for x in &p.x {
        let k = column_of(x[0], width, n);
        top[k] = top[k].max(x[1] + 0.5 * spacing);
    }
    top.iter()
        .enumerate()
        .filter(|(_, y)| y.is_finite())
        .map(|(k, &y)| ((k as f64 + 0.5) * width, y))
        .collect()
}

/// One sample of a collapse history.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Simulated time (s).
    pub t: f64,
    /// Toe position, threshold [`MIN_THICKNESS`] (m).
    pub toe: f64,
    /// Toe of any contiguous material (threshold: a column is not empty) (m).
    pub film_toe: f64,
    /// Height at the wall (m).
    pub wall_height: f64,
    /// Kinetic energy `K` (J/m).
    pub kinetic: f64,
    /// Potential energy released since `t = 0`, `ΔE_p` (J/m).
    pub released: f64,
}

/// The result of a collapse run.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The set-up.
    pub collapse: Collapse,
    /// History, `t = 0` included.
    pub history: Vec<Sample>,
    /// Final thickness profile per column `(x, t)`.
    pub thickness: Vec<(f64, f64)>,
    /// Final thickness profile averaged over [`WINDOW`] `(x, t)` (what [`toe`] thresholds).
    pub smoothed: Vec<(f64, f64)>,
    /// Final free surface `(x, y)`.
    pub surface: Vec<(f64, f64)>,
    /// Largest `x_p + d_p/2` of any particle at the end (m).
    pub max_x: f64,
    /// Particle count.
    pub particles: usize,
    /// Steps taken.
    pub steps: usize,
    /// Wall-clock time of the run (s).
    pub wall: f64,
}

impl Outcome {
    /// The last sample.
    pub fn last(&self) -> Sample {
        *self.history.last().expect("the history holds t = 0")
    }

    /// Final toe `L∞` (m).
    pub fn runout(&self) -> f64 {
        self.last().toe
    }

    /// Normalised runout `(L∞ − L₀)/L₀`.
    pub fn normalised_runout(&self) -> f64 {
        (self.runout() - self.collapse.l0) / self.collapse.l0
    }

    /// `K/ΔE_p` at the end.
    pub fn rest_ratio(&self) -> f64 {
        let s = self.last();
        s.kinetic / s.released
    }

    /// How far the toe moved over the last `fraction` of the run (m): zero once the front has
    /// stopped.
    pub fn late_toe_motion(&self, fraction: f64) -> f64 {
        let t0 = (1.0 - fraction) * self.collapse.end_time * (1.0 - 1e-9);
        let (lo, hi) = self
            .history
            .iter()
            .filter(|s| s.t >= t0)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
                (a.min(s.toe), b.max(s.toe))
            });
        hi - lo
    }

    /// Cells between the rightmost particle and the right wall (the box must be long enough
    /// for the deposit not to reach it).
    pub fn right_clearance_cells(&self) -> f64 {
        (self.collapse.length - self.max_x) / self.collapse.h
    }
}

/// Runs a collapse on `device` to its end time, sampling the history `samples` times at equal
/// intervals.
pub fn simulate(
    case: &'static str,
    c: &Collapse,
    device: &Device,
    samples: usize,
) -> Result<Outcome, VerifyError> {
    let (config, mut particles) = build(c);
    let mut solver = ExplicitRun::new(case, config, &particles, device)?;
    let (w, dp, rho) = (c.h, c.spacing(), c.material.density);
    let e0 = solver.energy(&particles).gravity;
    let sample = |s: &ExplicitRun<2>, p: &Particles<f64, 2>, t: f64| {
        let e = s.energy(p);
        Sample {
            t,
            toe: toe(p, w, c.length, rho, WINDOW, MIN_THICKNESS, dp),
            film_toe: toe(p, w, c.length, rho, w, f64::MIN_POSITIVE, dp),
            wall_height: wall_height(p, w, dp),
            kinetic: e.kinetic,
            released: e0 - e.gravity,
        }
    };
    let start = std::time::Instant::now();
    let mut history = vec![sample(&solver, &particles, 0.0)];
    for k in 1..=samples {
        let t = c.end_time * k as f64 / samples as f64;
        solver.advance(&mut particles, t)?;
        history.push(sample(&solver, &particles, t));
    }
    let wall = start.elapsed().as_secs_f64();
    Ok(Outcome {
        collapse: *c,
        history,
        thickness: thickness_profile(&particles, w, c.length, rho, w),
        smoothed: thickness_profile(&particles, w, c.length, rho, WINDOW),
        surface: surface(&particles, w, c.length, dp),
        max_x: particles.x.iter().map(|x| x[0]).fold(0.0, f64::max) + 0.5 * dp,
        particles: particles.len(),
        steps: solver.steps(),
        wall,
    })
}

/// Writes the history of a run as CSV.
pub fn write_history(path: &Path, o: &Outcome) -> Result<(), VerifyError> {
    let rows: Vec<Vec<f64>> = o
        .history
        .iter()
        .map(|s| vec![s.t, s.toe, s.film_toe, s.wall_height, s.kinetic, s.released])
        .collect();
    write_csv(
        path,
        &["t", "toe", "film_toe", "wall_height", "kinetic", "released"],
        &rows,
    )
}

/// Writes the final deposit as CSV: per column, `x`, the solid-equivalent thickness of the
/// column, the same averaged over [`WINDOW`], and the free surface (`NaN` over empty columns).
pub fn write_deposit(path: &Path, o: &Outcome) -> Result<(), VerifyError> {
    write_csv(
        path,
        &["x", "thickness", "thickness_smoothed", "surface"],
        &deposit_rows(o),
    )
}

/// Rows `x, thickness, smoothed thickness, surface` of the final deposit.
pub fn deposit_rows(o: &Outcome) -> Vec<Vec<f64>> {
    o.thickness
        .iter()
        .zip(&o.smoothed)
        .map(|(&(x, t), &(_, ts))| {
            let top = o
                .surface
                .iter()
                .find(|(xs, _)| (xs - x).abs() < 1e-9)
                .map_or(f64::NAN, |&(_, y)| y);
            vec![x, t, ts, top]
        })
        .collect()
}

/// The outline of the initial column, `(0, H₀) → (L₀, H₀) → (L₀, 0)`, scaled by `1/scale`.
pub fn initial_outline(c: &Collapse, scale: f64) -> Vec<(f64, f64)> {
    vec![
        (0.0, c.h0 / scale),
        (c.l0 / scale, c.h0 / scale),
        (c.l0 / scale, 0.0),
    ]
}

/// The final thickness profile averaged over [`WINDOW`] as a plot series, up to the last
/// non-empty column, with both axes scaled by `1/scale`.
pub fn thickness_series(o: &Outcome, name: &str, scale: f64) -> Series {
    let last = o.thickness.iter().rposition(|&(_, t)| t > 0.0).unwrap_or(0);
    Series {
        name: name.into(),
        points: o.smoothed[..=last]
            .iter()
            .map(|&(x, t)| (x / scale, t / scale))
            .collect(),
        markers: false,
    }
}
