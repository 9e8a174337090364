//! The scenes of the parity tests, written from their parts: a box of one material (and
//! more boxes of other materials where a scene has them) in a walled rectangle (2D) or box
//! (3D) under gravity along −y, with friction segments or obstacles where a scene has them.

/// One test scene; [`SceneText::toml`] writes its scene file for a scheme and a transfer.
#[derive(Clone, Debug)]
pub struct SceneText<const D: usize> {
    /// `grid.hi` (`grid.lo` is the origin).
    pub hi: [f64; D],
    /// `grid.shape_function`.
    pub shape: &'static str,
    /// `grid.cell_size`.
    pub cell_size: f64,
    /// The keys of the one material after its name ([`water`], [`solid`]).
    pub material: String,
    /// The body: a box from `body[0]` to `body[1]`, two particles per cell.
    pub body: [[f64; D]; 2],
    /// The `y_min` wall; every other face is a bilateral slip wall.
    pub floor: &'static str,
    /// Whether `y_max` is a wall too (else that face is free).
    pub ceiling: bool,
    /// Tables between the boundaries and the loads: friction segments ([`segment`]),
    /// obstacles ([`column`]).
    pub contact: String,
    /// `g` of the gravity `(0, −g[, 0])`.
    pub gravity: f64,
    /// `solver.time_step` ([`fixed`], or an adaptive table).
    pub time_step: String,
    /// Further materials and bodies (`[[materials]]` and `[[bodies]]` tables), after the
    /// first ones.
    pub more: String,
}

/// A separable (unilateral) slip floor.
pub const SEPARABLE_SLIP: &str = "{ kind = \"slip\", separable = true }";

/// The FLIP transfer of the parity tests, `α = 0.95` (5 % of PIC per step).
pub const FLIP: &str = "{ type = \"flip\", alpha = 0.95 }";

/// `solver.time_step` for a fixed step `dt`.
pub fn fixed(dt: f64) -> String {
    format!("{{ type = \"fixed\", dt = {dt:?} }}")
}

/// The weakly compressible water of the examples (1000 kg/m³, γ = 7, inviscid) at sound
/// speed `c`.
pub fn water(c: f64) -> String {
    format!(
        "model = \"fluid\"\ndensity = 1000.0\nsound_speed = {c:?}\ngamma = 7.0\nviscosity = 0.0"
    )
}

/// A solid of `model` with density `rho`, Young's modulus `e` and ν = 0.3; `more` takes
/// further keys (one per line).
pub fn solid(model: &str, rho: f64, e: f64, more: &str) -> String {
    format!(
        "model = \"{model}\"\ndensity = {rho:?}\nyoungs_modulus = {e:?}\npoisson_ratio = 0.3\n{more}"
    )
}

/// A Coulomb segment of friction `mu` on the floor, over `[from, to]` along x (the whole
/// face when `None`).
pub fn segment(mu: f64, range: Option<(f64, f64)>) -> String {
    let range = range.map_or(String::new(), |(a, b)| {
        format!("from = [{a:?}]\nto = [{b:?}]\n")
    });
    format!("[[friction]]\nwall = \"y_min\"\nmu = {mu:?}\n{range}\n")
}

/// A rigid column along y through the 3D domain's height of 0.4 m, 0.08 m in radius, at
/// `(x, z)`.
pub fn column(x: f64, z: f64) -> String {
    format!(
        "[[obstacles]]\nshape = \"cylinder\"\ncentre = [{x:?}, 0.2, {z:?}]\nradius = 0.08\n\
         axis = \"y\"\nlength = 0.4\n\n"
    )
}

/// A TOML array of `D` numbers.
fn array<const D: usize>(x: [f64; D]) -> String {
    format!("{x:?}")
}

impl<const D: usize> SceneText<D> {
    /// The scene file with `solver.scheme = scheme` and `solver.transfer = transfer` (a
    /// transfer's name, or a table such as [`FLIP`]).
    pub fn toml(&self, scheme: &str, transfer: &str) -> String {
        let transfer = if transfer.starts_with('{') {
            transfer.to_string()
        } else {
            format!("\"{transfer}\"")
        };
        let mut walls = String::new();
        for (a, axis) in ["x", "y", "z"].iter().take(D).enumerate() {
            let lo = if a == 1 { self.floor } else { "\"slip\"" };
            walls += &format!("{axis}_min = {lo}\n");
            if a != 1 || self.ceiling {
                walls += &format!("{axis}_max = \"slip\"\n");
            }
        }
        let mut gravity = [0.0; D];
        gravity[1] = -self.gravity;
        format!(
            "[grid]\nlo = {lo}\nhi = {hi}\ncell_size = {h:?}\nshape_function = \"{shape}\"\n\n\
             [[materials]]\nname = \"m\"\n{material}\n\n\
             [[bodies]]\nmaterial = \"m\"\nshape = {{ type = \"box\", lo = {body_lo}, hi = {body_hi} }}\n\
             particles_per_cell = 2\n\n{more}\
             [boundaries]\n{walls}\n{contact}\
             [loads]\ngravity = {gravity}\n\n\
             [solver]\ntype = \"explicit\"\nscheme = \"{scheme}\"\ntransfer = {transfer}\n\
             time_step = {time_step}\nend_time = 1.0\n",
            lo = array([0.0; D]),
            hi = array(self.hi),
            h = self.cell_size,
            shape = self.shape,
            material = self.material,
            body_lo = array(self.body[0]),
            body_hi = array(self.body[1]),
            contact = self.contact,
            gravity = array(gravity),
            time_step = self.time_step,
            more = self.more,
        )
    }
}

/// The 2D dam-break of examples/dam_break.toml at 0.02 m (100 × 6 cells, 1,000 particles),
/// with a fixed step of 1e-4 s (the example's `max_dt`).
pub fn dam_break_2d() -> SceneText<2> {
    SceneText {
        hi: [2.0, 0.12],
        shape: "quadratic_bspline",
        cell_size: 0.02,
        material: water(35.0),
        body: [[0.0; 2], [1.0, 0.1]],
        floor: "\"slip\"",
        ceiling: true,
        contact: String::new(),
        gravity: 9.8,
        time_step: fixed(1e-4),
        more: String::new(),
    }
}

/// The friction dam-break of examples/dambreak_friction.toml at 0.02 m (100 × 20 cells,
/// 1,500 particles): five Coulomb segments on a separable slip floor (μ = 0, 0.5, 0.1, 0.2,
/// 0), fixed step 6e-5 s (the example's CFL 0.1 at this cell size).
pub fn friction_2d() -> SceneText<2> {
    let mu = [0.0, 0.5, 0.1, 0.2, 0.0];
    let ends = [0.0, 0.4, 0.8, 1.2, 1.6, 2.0];
    SceneText {
        hi: [2.0, 0.4],
        body: [[0.0; 2], [0.5, 0.3]],
        floor: SEPARABLE_SLIP,
        contact: (0..5)
            .map(|k| segment(mu[k], Some((ends[k], ends[k + 1]))))
            .collect(),
        time_step: fixed(6e-5),
        ..dam_break_2d()
    }
}

/// A disk obstacle of radius `r` at `(x, y)` (a 2D cylinder).
pub fn disk(x: f64, y: f64, r: f64) -> String {
    format!("[[obstacles]]\nshape = \"cylinder\"\ncentre = [{x:?}, {y:?}]\nradius = {r:?}\n\n")
}

/// The 2D dam-break of [`dam_break_2d`] running into a field of 20 baffles: disks of radius
/// 0.015 m, 0.045 m apart along x from x = 1.045 m, staggered at y = 0.03 and 0.07 m, listed
/// from the far end, so that the ones the surge reaches first are obstacles 19, 18, 17 …
/// (past the 16 that fit in the first word of a node's state on the GPU).
pub fn baffles_2d() -> SceneText<2> {
    SceneText {
        contact: (0..20)
            .map(|k| {
                let x = 1.9 - 0.045 * k as f64;
                disk(x, if k % 2 == 0 { 0.03 } else { 0.07 }, 0.015)
            })
            .collect(),
        ..dam_break_2d()
    }
}

/// The elastic block drop of examples/elastic_block_drop.toml, widened to 0.4 m × 0.3 m
/// (0.02 m cells, 1,200 particles): the block falls 0.3 m onto a unilateral no-slip floor
/// (impact at t ≈ 0.25 s, 2.4 m/s) and rebounds. `model` is `neo_hookean` or `hencky` (E = 1e5 Pa, ν = 0.3); a fixed step of
/// 5e-4 s (CFL 0.4 at the wave speed, 11.6 m/s, plus the impact speed).
pub fn block_drop_2d(model: &str) -> SceneText<2> {
    SceneText {
        hi: [1.0, 1.0],
        material: solid(model, 1000.0, 1.0e5, ""),
        body: [[0.3, 0.3], [0.7, 0.6]],
        floor: "{ kind = \"no_slip\", separable = true }",
        gravity: 9.81,
        time_step: fixed(5e-4),
        ..dam_break_2d()
    }
}

/// Two blocks of different models side by side, a Neo-Hookean one and a Hencky one, dropped
/// as in [`block_drop_2d`] (each 0.3 × 0.3 m, 900 particles): one kernel holds both models'
/// updates and picks each particle's from its material.
pub fn two_models_2d() -> SceneText<2> {
    SceneText {
        body: [[0.1, 0.3], [0.4, 0.6]],
        more: format!(
            "[[materials]]\nname = \"h\"\n{}\n\n[[bodies]]\nmaterial = \"h\"\n\
             shape = {{ type = \"box\", lo = [0.6, 0.3], hi = [0.9, 0.6] }}\n\
             particles_per_cell = 2\n\n",
            solid("hencky", 1000.0, 1.0e5, "")
        ),
        ..block_drop_2d("neo_hookean")
    }
}

/// The 3D dam-break of examples/dambreak_obstacles_3d.toml without its columns, at 0.05 m
/// (24 × 8 × 12 cells, 4,608 particles), a separable slip floor, fixed step 5e-4 s (CFL 0.3
/// at the sound speed).
pub fn dam_break_3d() -> SceneText<3> {
    SceneText {
        hi: [1.2, 0.4, 0.6],
        shape: "quadratic_bspline",
        cell_size: 0.05,
        material: water(30.0),
        body: [[0.0; 3], [0.4, 0.3, 0.6]],
        floor: SEPARABLE_SLIP,
        ceiling: true,
        contact: String::new(),
        gravity: 9.81,
        time_step: fixed(5e-4),
        more: String::new(),
    }
}

/// The 3D dam-break of examples/dambreak_obstacles_3d.toml at 0.05 m (4,608 particles) with
/// its two columns widened to 0.08 m (the example keeps the radius at least 1.5 cells), on a
/// bilateral slip floor, fixed step 5e-4 s: by step 400 (0.2 s) the surge has run into the
/// columns.
pub fn obstacles_3d() -> SceneText<3> {
    SceneText {
        floor: "\"slip\"",
        contact: column(0.7, 0.15) + &column(0.7, 0.45),
        ..dam_break_3d()
    }
}

/// The 3D granular column collapse of examples/granular_collapse_3d.toml (a quarter of a
/// column of cohesionless Drucker–Prager sand, φ = 30°, ψ = 0, on a Coulomb floor with
/// μ = tan φ; 0.01 m cells, the top of the domain free), made smaller for the software
/// adapter of CI: a 0.04 × 0.08 × 0.04 m quarter column (1,024 particles) in a
/// 0.2 × 0.1 × 0.2 m domain (in 0.1 s the front moves about 5 cm, free fall's `g t²/2`, so it
/// stays well inside), with a fixed step of 2e-4 s (CFL 0.4 at the elastic wave speed,
/// 20.6 m/s). `more` takes more keys of the material (cohesion, tension cutoff).
pub fn column_3d(more: &str) -> SceneText<3> {
    let sand = "friction_angle = 30.0\ndilation_angle = 0.0\n".to_string() + more;
    SceneText {
        hi: [0.2, 0.1, 0.2],
        cell_size: 0.01,
        material: solid("drucker_prager", 2650.0, 0.84e6, &sand),
        body: [[0.0; 3], [0.04, 0.08, 0.04]],
        ceiling: false,
        contact: segment(0.5774, None),
        time_step: fixed(2e-4),
        ..dam_break_3d()
    }
}
