//! Scenes and helpers shared by the integration tests of `loam-inverse`.

use loam_core::Particles;
use loam_explicit::Config;
use loam_scene::Scene;

/// The solver inputs of a scene file's text.
pub fn scene<const D: usize>(toml: &str) -> (Config<f64, D>, Particles<f64, D>) {
    let built = Scene::from_toml_str(toml)
        .and_then(|s| s.build::<D>())
        .unwrap_or_else(|e| panic!("{e}"));
    (built.explicit_config().expect("explicit"), built.particles)
}

/// Water (MLS-MPM, USL) on a floor of two Coulomb segments, a bilateral slip wall behind it.
pub const FLUID_2D: &str = r#"
[grid]
lo = [0.0, 0.0]
hi = [0.4, 0.2]
cell_size = 0.02
shape_function = "quadratic_bspline"

[[materials]]
name = "water"
model = "fluid"
density = 1000.0
sound_speed = 10.0
gamma = 7.0
viscosity = 0.05

[[bodies]]
material = "water"
shape = { type = "box", lo = [0.0, 0.0], hi = [0.12, 0.1] }
particles_per_cell = 2
velocity = [0.3, 0.0]

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = { kind = "slip", separable = true }
y_max = "slip"

[[friction]]
wall = "y_min"
mu = 0.3
from = [0.0]
to = [0.06]

[[friction]]
wall = "y_min"
mu = 0.1
from = [0.06]
to = [0.4]

[loads]
gravity = [0.0, -9.81]

[solver]
type = "explicit"
scheme = "usl"
transfer = "mls"
time_step = { type = "fixed", dt = 5e-4 }
end_time = 0.03
"#;
