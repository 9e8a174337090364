//! Observation files (CSV): reading them onto the steps of a run, writing synthetic ones,
//! and the choice of tracked particles.
//!
//! Tracked positions: a header `step,id,x,y` (2D; `z` too in 3D) or `time,id,x,y`, then one
//! row per particle and observed step. Monitor velocities: `step,monitor,vx,vy` (`vz`) or
//! `time,...`, one row per monitor and observed step, `monitor` a name of
//! `[[observations.monitors]]`. Deposit depths: `step,station,depth` or `time,...`, one row
//! per station and observed step, `station` a name of `[[observations.stations]]`. A time
//! must fall on a step (`t = n Δt` within 10⁻³ Δt).
//!
//! Implicit runs: particle displacements `step,id,ux,uy` (`uz`) and reactions
//! `step,reaction,force`, `reaction` a name of `[[observations.reactions]]`, `step` a load
//! step (a `time` column is the load factor `step / load_steps`).
//! Blank lines and lines starting with `#` are skipped.

use loam_core::tensor::Vector;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// What observation rows are checked against.
pub struct Grid {
    /// The fixed time step.
    pub dt: f64,
    /// Steps of the run.
    pub steps: usize,
    /// Particles in the scene.
    pub particles: usize,
}

/// Per step, `(index, observed vector)`.
pub type Targets<const D: usize> = BTreeMap<usize, Vec<(usize, Vector<f64, D>)>>;

/// Reads `file` as rows of `(step, key, D values)`, `key` mapped to an index by `key_of`;
/// `columns` names the key and the value columns.
fn read<const D: usize>(
    file: &Path,
    grid: &Grid,
    columns: (&str, [&str; 3]),
    key_of: &dyn Fn(&str) -> Result<usize, String>,
) -> Result<Targets<D>, String> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let mut lines = (text.lines().enumerate())
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let fail = |line: usize, msg: String| format!("{} line {line}: {msg}", file.display());
    let (key, values) = columns;
    let expected: Vec<&str> = std::iter::once(key)
        .chain(values[..D].iter().copied())
        .collect();
    let (line, header) = lines
        .next()
        .ok_or_else(|| fail(1, "the file is empty".into()))?;
    let cells: Vec<&str> = header.split(',').map(str::trim).collect();
    let by_time = match cells.first() {
        Some(&"step") => false,
        Some(&"time") => true,
        _ => {
            return Err(fail(
                line,
                format!(
                    "expected the header `step,{0}` or `time,{0}`",
                    expected.join(",")
                ),
            ));
        }
    };
    if cells[1..] != expected[..] {
        return Err(fail(
            line,
            format!("expected the header `{},{}`", cells[0], expected.join(",")),
        ));
    }
    let mut out = Targets::<D>::new();
    for (line, row) in lines {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        if cells.len() != D + 2 {
            return Err(fail(
                line,
                format!("expected {} values, got {}", D + 2, cells.len()),
            ));
        }
        let step = if by_time {
            let t: f64 = cells[0]
                .parse()
                .map_err(|_| fail(line, format!("`{}` is not a time", cells[0])))?;
            let n = (t / grid.dt).round();
            if !(n >= 0.0 && (t - n * grid.dt).abs() <= 1e-3 * grid.dt) {
                return Err(fail(
                    line,
                    format!("time {t} is not on a step of Δt = {}", grid.dt),
                ));
            }
            n as usize
        } else {
            cells[0]
                .parse()
                .map_err(|_| fail(line, format!("`{}` is not a step number", cells[0])))?
        };
        if step > grid.steps {
            return Err(fail(
                line,
                format!(
                    "step {step} is after the last step of the run, {}",
                    grid.steps
                ),
            ));
        }
        let index = key_of(cells[1]).map_err(|m| fail(line, m))?;
        let mut v = Vector::<f64, D>::zeros();
        for a in 0..D {
            v[a] = cells[2 + a]
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| fail(line, format!("`{}` is not a finite number", cells[2 + a])))?;
        }
        out.entry(step).or_default().push((index, v));
    }
    Ok(out)
}

/// Reads a tracked-positions file.
pub fn read_tracked<const D: usize>(file: &Path, grid: &Grid) -> Result<Targets<D>, String> {
    let n = grid.particles;
    read(
        file,
        grid,
        ("id", ["x", "y", "z"]),
        &|s| match s.parse::<usize>() {
            Ok(id) if id < n => Ok(id),
            _ => Err(format!(
                "`{s}` is not a particle id (0 to {})",
                n.saturating_sub(1)
            )),
        },
    )
}

/// Reads a particle-displacements file of an implicit run (`step` a load step).
pub fn read_displacement<const D: usize>(file: &Path, grid: &Grid) -> Result<Targets<D>, String> {
    let n = grid.particles;
    read(
        file,
        grid,
        ("id", ["ux", "uy", "uz"]),
        &|s| match s.parse::<usize>() {
            Ok(id) if id < n => Ok(id),
            _ => Err(format!(
                "`{s}` is not a particle id (0 to {})",
                n.saturating_sub(1)
            )),
        },
    )
}

/// Reads a reactions file of an implicit run: per load step, `(reaction, force)`.
pub fn read_reaction(
    file: &Path,
    grid: &Grid,
    reactions: &[String],
) -> Result<BTreeMap<usize, Vec<(usize, f64)>>, String> {
    let rows = read::<1>(file, grid, ("reaction", ["force", "", ""]), &|s| {
        reactions
            .iter()
            .position(|m| m == s)
            .ok_or_else(|| format!("unknown reaction `{s}`; defined: {}", reactions.join(", ")))
    })?;
    Ok(depths(&rows))
}

/// Reads a monitor-velocities file.
pub fn read_velocity<const D: usize>(
    file: &Path,
    grid: &Grid,
    monitors: &[String],
) -> Result<Targets<D>, String> {
    read(file, grid, ("monitor", ["vx", "vy", "vz"]), &|s| {
        monitors
            .iter()
            .position(|m| m == s)
            .ok_or_else(|| format!("unknown monitor `{s}`; defined: {}", monitors.join(", ")))
    })
}

/// Reads a deposit-depth file: per step, `(station, depth)`.
pub fn read_deposit(
    file: &Path,
    grid: &Grid,
    stations: &[String],
) -> Result<BTreeMap<usize, Vec<(usize, f64)>>, String> {
    let rows = read::<1>(file, grid, ("station", ["depth", "", ""]), &|s| {
        stations
            .iter()
            .position(|m| m == s)
            .ok_or_else(|| format!("unknown station `{s}`; defined: {}", stations.join(", ")))
    })?;
    Ok(depths(&rows))
}

/// Scalar targets (depths, reactions) from one-component vectors (the rows [`read`] gives).
fn depths(rows: &Targets<1>) -> BTreeMap<usize, Vec<(usize, f64)>> {
    (rows.iter())
        .map(|(&s, r)| (s, r.iter().map(|&(i, v)| (i, v[0])).collect()))
        .collect()
}

/// Writes targets as a CSV file read back by [`read_tracked`] or [`read_velocity`]
/// (`keys[i]` names index `i`; `None` writes the index).
pub fn write<const D: usize>(
    file: &Path,
    targets: &Targets<D>,
    key: &str,
    values: [&str; 3],
    keys: Option<&[String]>,
) -> std::io::Result<()> {
    let mut s = format!("step,{key},{}\n", values[..D].join(","));
    for (step, rows) in targets {
        for (i, v) in rows {
            let name = keys.map_or_else(|| i.to_string(), |k| k[*i].clone());
            let v: Vec<String> = v.iter().map(|x| format!("{x:e}")).collect();
            writeln!(s, "{step},{name},{}", v.join(",")).expect("writing to a String");
        }
    }
    std::fs::write(file, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_observations_read_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("tracked.csv");
        let mut t = Targets::<2>::new();
        t.insert(
            10,
            vec![
                (3, Vector::from([0.1, 1.0 / 3.0])),
                (7, Vector::from([2.5e-7, -4.0])),
            ],
        );
        t.insert(20, vec![(3, Vector::from([0.2, 0.3]))]);
        write(&file, &t, "id", ["x", "y", "z"], None).unwrap();
        let grid = Grid {
            dt: 1e-3,
            steps: 20,
            particles: 8,
        };
        assert_eq!(read_tracked::<2>(&file, &grid).unwrap(), t);
        // Times on steps are accepted; an unknown id is reported with its line.
        std::fs::write(
            &file,
            "# positions\ntime,id,x,y\n0.01,3,0.1,0.2\n0.02,9,0,0\n",
        )
        .unwrap();
        let err = read_tracked::<2>(&file, &grid).unwrap_err();
        assert!(err.contains("line 4") && err.contains("`9`"), "{err}");
    }
}
