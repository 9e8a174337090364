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
//! Implicit runs: particle displacements `step,id,ux,uy` (`uz`), reactions
//! `step,reaction,force`, `reaction` a name of `[[observations.reactions]]`, and pore
//! pressures `step,piezometer,pore_pressure`, `piezometer` a name of
//! `[[observations.piezometers]]`; `step` a load step (a `time` column is the load factor
//! `step / load_steps`, or in a coupled run the consolidation schedule's time at the end of
//! a step, in the scene's `time_unit`).
//! Blank lines and lines starting with `#` are skipped, and so is a byte-order mark (as a
//! spreadsheet saving "CSV UTF-8" writes) before the header.

use loam_core::tensor::Vector;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// What observation rows are checked against.
pub struct Grid {
    /// The fixed time step.
    pub dt: f64,
    /// Where the steps are not uniform (a coupled run's consolidation schedule), the time at
    /// the end of each step `1..=steps`, in the unit of the file's `time` column; a `time`
    /// then names the step that ends there.
    pub times: Option<Vec<f64>>,
    /// Steps of the run.
    pub steps: usize,
    /// Particles in the scene.
    pub particles: usize,
    /// The scene's domain `[lo, hi]` (m), `grid.lo` and `grid.hi`.
    pub domain: (Vec<f64>, Vec<f64>),
    /// The grid's cell size (m).
    pub cell: f64,
}

impl Grid {
    /// The step of a non-uniform schedule that ends at time `t` (`times`, [`Grid::times`]),
    /// within 1e-6 of the step's length; 0 for `t = 0`, the initial state.
    fn scheduled_step(&self, times: &[f64], t: f64) -> Result<usize, String> {
        if t == 0.0 {
            return Ok(0);
        }
        let mut previous = 0.0;
        for (k, &end) in times.iter().enumerate() {
            if (t - end).abs() <= 1e-6 * (end - previous).abs().max(f64::MIN_POSITIVE) {
                return Ok(k + 1);
            }
            previous = end;
        }
        let shown: Vec<String> = times.iter().take(8).map(|v| format!("{v:.6e}")).collect();
        Err(format!(
            "time {t} is not the end of a step of the consolidation schedule, whose {} steps \
             end at {}{} (in the scene's time_unit)",
            times.len(),
            shown.join(", "),
            if times.len() > 8 { ", …" } else { "" }
        ))
    }

    /// The position `x` (m), or why it cannot be one: particles stay on the grid, so a
    /// position more than a cell outside the domain is not one of theirs (positions in
    /// millimetres, say).
    fn position<const D: usize>(&self, x: &Vector<f64, D>) -> Result<(), String> {
        let (lo, hi) = &self.domain;
        let inside = (0..D).all(|a| x[a] >= lo[a] - self.cell && x[a] <= hi[a] + self.cell);
        if inside {
            return Ok(());
        }
        Err(format!(
            "position {} m is outside the grid, [{}] to [{}] m by more than a cell: positions \
             are in metres",
            coordinates(x.as_slice()),
            coordinates(lo),
            coordinates(hi)
        ))
    }

    /// The displacement `u` (m), or why it cannot be one: larger than the domain along an
    /// axis (by more than a cell), it would take a particle off the grid.
    fn displacement<const D: usize>(&self, u: &Vector<f64, D>) -> Result<(), String> {
        let (lo, hi) = &self.domain;
        if (0..D).all(|a| u[a].abs() <= hi[a] - lo[a] + self.cell) {
            return Ok(());
        }
        Err(format!(
            "displacement {} m is larger than the grid, [{}] to [{}] m: displacements are in \
             metres",
            coordinates(u.as_slice()),
            coordinates(lo),
            coordinates(hi)
        ))
    }

    /// The depth `h` (m) along the vertical axis `up`, or why it cannot be one: negative, or
    /// higher than the domain (by more than a cell).
    fn depth(&self, h: f64, up: usize) -> Result<(), String> {
        let height = self.domain.1[up] - self.domain.0[up];
        if (0.0..=height + self.cell).contains(&h) {
            return Ok(());
        }
        Err(format!(
            "depth {h} m is not between 0 and the height of the grid, {height} m: depths are \
             in metres"
        ))
    }
}

/// `a, b, c` for coordinates.
fn coordinates(x: &[f64]) -> String {
    x.iter()
        .map(|v| format!("{v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A value check of a row, which passes everything: velocities and reactions have no bound
/// that the scene sets.
fn any<const D: usize>(_: &Vector<f64, D>) -> Result<(), String> {
    Ok(())
}

/// Per step, `(index, observed vector)`.
pub type Targets<const D: usize> = BTreeMap<usize, Vec<(usize, Vector<f64, D>)>>;

/// Reads `file` as rows of `(step, key, D values)`, `key` mapped to an index by `key_of`
/// and the values checked by `value_ok`; `columns` names the key and the value columns.
/// Each problem names the line: a row given twice for one step and key, a file with no rows,
/// or with rows at step 0 (the initial state, which no parameter moves) only.
fn read<const D: usize>(
    file: &Path,
    grid: &Grid,
    columns: (&str, [&str; 3]),
    key_of: &dyn Fn(&str) -> Result<usize, String>,
    value_ok: &dyn Fn(&Vector<f64, D>) -> Result<(), String>,
) -> Result<Targets<D>, String> {
    let text =
        loam_scene::read_csv(file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
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
    // The line of each (step, index) and the first row's line.
    let mut seen: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    let mut first_row = None;
    for (line, row) in lines {
        first_row.get_or_insert(line);
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
            match &grid.times {
                Some(times) => grid.scheduled_step(times, t).map_err(|m| fail(line, m))?,
                None => {
                    let n = (t / grid.dt).round();
                    if !(n >= 0.0 && (t - n * grid.dt).abs() <= 1e-3 * grid.dt) {
                        return Err(fail(
                            line,
                            format!("time {t} is not on a step of Δt = {}", grid.dt),
                        ));
                    }
                    n as usize
                }
            }
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
        value_ok(&v).map_err(|m| fail(line, m))?;
        if let Some(earlier) = seen.insert((step, index), line) {
            return Err(fail(
                line,
                format!(
                    "step {step}, {key} `{}` is given again (first on line {earlier}): one row \
                     per {key} and step",
                    cells[1]
                ),
            ));
        }
        out.entry(step).or_default().push((index, v));
    }
    let Some(first_row) = first_row else {
        return Err(fail(
            line,
            "a header and no rows: nothing to observe (the loss would be 0 whatever the \
             parameters)"
                .into(),
        ));
    };
    if out.keys().all(|&s| s == 0) {
        return Err(fail(
            first_row,
            "every row is at step 0, the initial state, which no parameter moves: expected \
             rows after step 0 (a time column in the wrong unit?)"
                .into(),
        ));
    }
    Ok(out)
}

impl Grid {
    /// The index of the particle id `s`, or why it is not one.
    fn particle(&self, s: &str) -> Result<usize, String> {
        let n = self.particles;
        match s.parse::<usize>() {
            Ok(id) if id < n => Ok(id),
            _ => Err(format!(
                "`{s}` is not a particle id (0 to {})",
                n.saturating_sub(1)
            )),
        }
    }
}

/// The index of a name among `names` (the key column of a file), or why it is not one of
/// them (`what`: `monitor`, `station`, `reaction`).
fn named<'a>(what: &'a str, names: &'a [String]) -> impl Fn(&str) -> Result<usize, String> + 'a {
    move |s| {
        names
            .iter()
            .position(|m| m == s)
            .ok_or_else(|| format!("unknown {what} `{s}`; defined: {}", names.join(", ")))
    }
}

/// Reads a tracked-positions file (positions on the grid).
pub fn read_tracked<const D: usize>(file: &Path, grid: &Grid) -> Result<Targets<D>, String> {
    read(
        file,
        grid,
        ("id", ["x", "y", "z"]),
        &|s| grid.particle(s),
        &|x| grid.position(x),
    )
}

/// Reads a particle-displacements file of an implicit run (`step` a load step; each
/// displacement within the grid's size).
pub fn read_displacement<const D: usize>(file: &Path, grid: &Grid) -> Result<Targets<D>, String> {
    read(
        file,
        grid,
        ("id", ["ux", "uy", "uz"]),
        &|s| grid.particle(s),
        &|u| grid.displacement(u),
    )
}

/// Reads a reactions file of an implicit run: per load step, `(reaction, force)`.
pub fn read_reaction(
    file: &Path,
    grid: &Grid,
    reactions: &[String],
) -> Result<BTreeMap<usize, Vec<(usize, f64)>>, String> {
    let rows = read::<1>(
        file,
        grid,
        ("reaction", ["force", "", ""]),
        &named("reaction", reactions),
        &any,
    )?;
    Ok(depths(&rows))
}

/// Reads a pore-pressure CSV (`step|time, piezometer, pore_pressure`; Pa): per step, the
/// index of each named piezometer (in `piezometers`) and its reading.
///
pub fn read_pore_pressure(
    file: &Path,
    grid: &Grid,
    piezometers: &[String],
) -> Result<BTreeMap<usize, Vec<(usize, f64)>>, String> {
    let rows = read::<1>(
        file,
        grid,
        ("piezometer", ["pore_pressure", "", ""]),
        &named("piezometer", piezometers),
        &any,
    )?;
    Ok(depths(&rows))
}

/// Reads a monitor-velocities file.
pub fn read_velocity<const D: usize>(
    file: &Path,
    grid: &Grid,
    monitors: &[String],
) -> Result<Targets<D>, String> {
    read(
        file,
        grid,
        ("monitor", ["vx", "vy", "vz"]),
        &named("monitor", monitors),
        &any,
    )
}

/// Reads a deposit-depth file: per step, `(station, depth)`, each depth between 0 and the
/// grid's height along the vertical axis `up`.
pub fn read_deposit(
    file: &Path,
    grid: &Grid,
    stations: &[String],
    up: usize,
) -> Result<BTreeMap<usize, Vec<(usize, f64)>>, String> {
    let rows = read::<1>(
        file,
        grid,
        ("station", ["depth", "", ""]),
        &named("station", stations),
        &|h| grid.depth(h[0], up),
    )?;
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

    /// 20 steps of 1 ms, 8 particles, on the grid [-4, 4]² m of 0.1 m cells.
    fn grid() -> Grid {
        Grid {
            dt: 1e-3,
            times: None,
            steps: 20,
            particles: 8,
            domain: (vec![-4.0, -4.0], vec![4.0, 4.0]),
            cell: 0.1,
        }
    }

    /// The error of reading `text` as a tracked-positions file.
    fn refused(text: &str) -> String {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("tracked.csv");
        std::fs::write(&file, text).unwrap();
        read_tracked::<2>(&file, &grid()).unwrap_err()
    }

    /// A coupled run's schedule (steps ending at 0, 0.5, 1.5 and 3.5 days): a `time` names
    /// the step that ends there, to 1e-6 of its length; a time between two ends is refused
    /// with the steps' times.
    #[test]
    fn times_of_a_schedule_name_the_step_that_ends_there() {
        let mut g = grid();
        g.times = Some(vec![0.0, 0.5, 1.5, 3.5]);
        g.steps = 4;
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("p.csv");
        let names = ["upper".to_owned()];
        let read = |text: &str| {
            std::fs::write(&file, text).unwrap();
            read_pore_pressure(&file, &g, &names)
        };
        let t =
            read("time,piezometer,pore_pressure\n1.5,upper,10.0\n3.5000001,upper,5.0\n").unwrap();
        assert_eq!(t[&3], vec![(0, 10.0)]);
        assert_eq!(t[&4], vec![(0, 5.0)]);
        let err = read("time,piezometer,pore_pressure\n1.0,upper,10.0\n").unwrap_err();
        assert!(
            err.contains("line 2") && err.contains("not the end of a step") && err.contains("1.5"),
            "{err}"
        );
    }

    #[test]
    fn implausible_observations_are_refused_with_their_line() {
        // Millimetres: 250 mm read as 250 m, far off the 8 m × 8 m grid.
        let err = refused("step,id,x,y\n10,3,0.1,0.2\n10,4,250.0,30.0\n");
        assert!(
            err.contains("line 3") && err.contains("outside the grid") && err.contains("metres"),
            "{err}"
        );
        // A position of 1e300 m.
        assert!(refused("step,id,x,y\n10,3,1e300,0.2\n").contains("line 2"));
        // Within a cell of the domain is a position.
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("tracked.csv");
        std::fs::write(&file, "step,id,x,y\n10,3,-4.05,4.05\n").unwrap();
        assert!(read_tracked::<2>(&file, &grid()).is_ok());
        // One particle twice at one step, with different values (or the same).
        let err = refused("step,id,x,y\n10,3,0.1,0.2\n20,3,0.1,0.2\n10,3,0.1,0.3\n");
        assert!(
            err.contains("line 4") && err.contains("first on line 2") && err.contains("`3`"),
            "{err}"
        );
        // A header and nothing else: nothing observed.
        let err = refused("# tracked\nstep,id,x,y\n\n");
        assert!(err.contains("line 2") && err.contains("no rows"), "{err}");
        // The initial state only.
        let err = refused("time,id,x,y\n0.0,3,0.1,0.2\n0,4,0.1,0.2\n");
        assert!(err.contains("line 2") && err.contains("step 0"), "{err}");
    }

    #[test]
    fn a_spreadsheets_byte_order_mark_is_read_past() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("tracked.csv");
        std::fs::write(&file, "\u{feff}step,id,x,y\r\n10,3,0.1,0.2\r\n").unwrap();
        let t = read_tracked::<2>(&file, &grid()).unwrap();
        assert_eq!(t[&10], vec![(3, Vector::from([0.1, 0.2]))]);
    }

    #[test]
    fn depths_and_displacements_are_bounded_by_the_grid() {
        let g = grid();
        assert!(g.depth(0.5, 1).is_ok() && g.depth(8.05, 1).is_ok());
        assert!(g.depth(-0.01, 1).is_err() && g.depth(31.0, 1).is_err());
        assert!(g.displacement(&Vector::from([-8.0, 1.0])).is_ok());
        assert!(g.displacement(&Vector::from([0.0, -12.0])).is_err());
    }

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
        let grid = grid();
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
