//! Trajectories as a `movement` poses dataset (the neuroinformatics-unit's `movement`, which reads the
//! output of DeepLabCut, SLEAP and other trackers into one xarray layout and saves it as netCDF): what
//! `coevo --record OUT.nc` and the Python package's `save_trajectories("OUT.nc", ...)` write.
//!
//! The file is netCDF-3 (the 64-bit offset form, written by the pure-Rust `netcdf3` crate), which
//! `xarray.open_dataset` reads with any of its netCDF engines, holding what `movement` builds in
//! `ValidPosesInputs.to_dataset`:
//!
//! - `position` (time, space, keypoint, individual), float64, metres: x and y of each individual, one
//!   keypoint (`centroid`: an agent is a point), frame t the state at step t (frame 0 the spawned state),
//!   positions as simulated (on a torus, wrapped into the arena);
//! - `confidence` (time, keypoint, individual): 1 everywhere, for simulated positions are exact (a
//!   tracker gives its own score here; `movement` fills NaN when it has none);
//! - coordinates `time` (seconds: frame / fps, with fps = 1 / the scene's time step; or frame numbers
//!   when no fps is given), `space` (`x`, `y`), `keypoint` (`centroid`), `individual` (`predator_0`,
//!   …, `prey_0`, …: species and index within it, by coevo's agent id);
//! - `species` (individual): each individual's species, as `OUT-species.npy` names them beside an `.npy`;
//! - attributes `ds_type` = `poses`, `source_software` = `coevo`, `fps`, `time_unit` (`seconds` or
//!   `frames`), as `movement` sets them, and `coevo_version`.
//!
//! The dimension names are those of `movement` 0.17 and later (`keypoint`, `individual`); its releases
//! before 0.17 (the last for Python 3.11) named them `keypoints` and `individuals`, and read these files
//! after `ds.rename({"keypoint": "keypoints", "individual": "individuals"})`.
//! `python/tests/test_env.py` reads such files with xarray and checks them with the installed `movement`'s
//! own validator (renamed so where it is older).

use crate::io::Existing;
use std::io::{Cursor, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// The one keypoint of every individual.
const KEYPOINT: &str = "centroid";

/// Trajectories to write: `positions[frame][individual]` = (x, y) in metres, each individual's species.
pub struct Poses<'a> {
    pub positions: &'a [Vec<(f64, f64)>],
    pub species: &'a [String],
    /// Frames per second (1 / the time step); None: the time coordinate counts frames.
    pub fps: Option<f64>,
}

impl Poses<'_> {
    /// Each individual's name: its species and its index among that species' individuals.
    fn individuals(&self) -> Vec<String> {
        let mut seen = std::collections::BTreeMap::<&str, usize>::new();
        self.species
            .iter()
            .map(|s| {
                let k = seen.entry(s.as_str()).or_insert(0);
                *k += 1;
                format!("{s}_{}", *k - 1)
            })
            .collect()
    }

    /// Refuses what would make a file `movement` could not read or that would lie: no frame, frames of
    /// different sizes, species of another count, a non-finite position or a non-positive fps.
    fn check(&self) -> Result<(), String> {
        let n = self.species.len();
        if self.positions.is_empty() || n == 0 {
            return Err("no frame or no individual to write".into());
        }
        if let Some((t, f)) = self.positions.iter().enumerate().find(|(_, f)| f.len() != n) {
            return Err(format!("frame {t} holds {} individuals, the species list {n}", f.len()));
        }
        if let Some(t) = self.positions.iter().position(|f| f.iter().any(|(x, y)| !x.is_finite() || !y.is_finite())) {
            return Err(format!("frame {t} holds a non-finite position"));
        }
        if let Some(fps) = self.fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
            return Err(format!("fps {fps} is not a positive number"));
        }
        Ok(())
    }

    /// The file's bytes.
    fn to_netcdf(&self) -> Result<Vec<u8>, String> {
        let (frames, n) = (self.positions.len(), self.species.len());
        let individuals = self.individuals();
        let chars = |words: &[String]| -> (usize, Vec<u8>) {
            let width = words.iter().map(String::len).max().unwrap_or(1).max(1);
            let bytes = words.iter().flat_map(|w| w.bytes().chain(std::iter::repeat(0)).take(width)).collect();
            (width, bytes)
        };
        let (name_width, names) = chars(&individuals);
        let (species_width, species) = chars(self.species);
        let e = |e: netcdf3::error::InvalidDataSet| format!("{e:?}");
        let mut set = netcdf3::DataSet::new();
        for (dim, len) in [
            ("time", frames),
            ("space", 2),
            ("keypoint", 1),
            ("individual", n),
            ("string1", 1),
            ("string_keypoint", KEYPOINT.len()),
            ("string_individual", name_width),
            ("string_species", species_width),
        ] {
            set.add_fixed_dim(dim, len).map_err(e)?;
        }
        match self.fps {
            Some(_) => set.add_var_f64("time", &["time"]),
            None => set.add_var_i32("time", &["time"]),
        }
        .map_err(e)?;
        set.add_var_u8("space", &["space", "string1"]).map_err(e)?;
        set.add_var_u8("keypoint", &["keypoint", "string_keypoint"]).map_err(e)?;
        set.add_var_u8("individual", &["individual", "string_individual"]).map_err(e)?;
        set.add_var_f64("position", &["time", "space", "keypoint", "individual"]).map_err(e)?;
        set.add_var_f64("confidence", &["time", "keypoint", "individual"]).map_err(e)?;
        set.add_var_u8("species", &["individual", "string_species"]).map_err(e)?;
        // As xarray writes strings to netCDF-3, so that it reads them back as text, not bytes.
        for var in ["space", "keypoint", "individual", "species"] {
            set.add_var_attr_string(var, "_Encoding", "utf-8").map_err(e)?;
        }
        set.add_global_attr_string("ds_type", "poses").map_err(e)?;
        set.add_global_attr_string("source_software", "coevo").map_err(e)?;
        set.add_global_attr_string("coevo_version", crate::VERSION).map_err(e)?;
        if let Some(fps) = self.fps {
            set.add_global_attr_f64("fps", vec![fps]).map_err(e)?;
        }
        set.add_global_attr_string("time_unit", if self.fps.is_some() { "seconds" } else { "frames" }).map_err(e)?;

        // (time, space, keypoint, individual): per frame, every x, then every y.
        let mut position = Vec::with_capacity(frames * 2 * n);
        for frame in self.positions {
            position.extend(frame.iter().map(|p| p.0));
            position.extend(frame.iter().map(|p| p.1));
        }
        let bytes = SharedBuffer::default();
        let w = |e: netcdf3::error::WriteError| format!("{e:?}");
        let mut file = netcdf3::FileWriter::open_seek_write("poses.nc", Box::new(bytes.clone())).map_err(w)?;
        file.set_def(&set, netcdf3::Version::Offset64Bit, 0).map_err(w)?;
        match self.fps {
            Some(fps) => file.write_var_f64("time", &(0..frames).map(|t| t as f64 / fps).collect::<Vec<_>>()),
            None => file.write_var_i32("time", &(0..frames).map(|t| t as i32).collect::<Vec<_>>()),
        }
        .map_err(w)?;
        file.write_var_u8("space", b"xy").map_err(w)?;
        file.write_var_u8("keypoint", KEYPOINT.as_bytes()).map_err(w)?;
        file.write_var_u8("individual", &names).map_err(w)?;
        file.write_var_f64("position", &position).map_err(w)?;
        file.write_var_f64("confidence", &vec![1.0; frames * n]).map_err(w)?;
        file.write_var_u8("species", &species).map_err(w)?;
        file.close().map_err(w)?;
        Ok(bytes.take())
    }
}

/// Writes `poses` to `path` as a `movement` poses dataset (module docs), whole or not at all.
pub fn write(path: &Path, poses: &Poses, existing: Existing) -> crate::error::Result<()> {
    let fail = |why: String| -> crate::error::Error { format!("{}: {why}", path.display()).into() };
    poses.check().map_err(fail)?;
    if poses.positions.len() > i32::MAX as usize {
        return Err(fail("more frames than a netCDF-3 time coordinate holds".into()));
    }
    let bytes = poses.to_netcdf().map_err(fail)?;
    crate::io::write_file(path, existing, &bytes)
}

/// A growable in-memory file the netCDF writer seeks in, read back once it is closed (the writer owns
/// its output, so the bytes are shared).
#[derive(Clone, Default)]
struct SharedBuffer(Arc<Mutex<Cursor<Vec<u8>>>>);

impl SharedBuffer {
    fn take(&self) -> Vec<u8> {
        std::mem::take(self.0.lock().expect("not poisoned").get_mut())
    }
}

impl Write for SharedBuffer {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().expect("not poisoned").write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for SharedBuffer {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.0.lock().expect("not poisoned").seek(pos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_frames() -> (Vec<Vec<(f64, f64)>>, Vec<String>) {
        let positions = vec![vec![(1.0, 2.0), (3.0, 4.0), (5.0, 6.0)], vec![(1.5, 2.5), (3.5, 4.5), (5.5, 6.5)]];
        (positions, vec!["predator".into(), "prey".into(), "prey".into()])
    }

    #[test]
    fn the_file_reads_back_with_movement_s_layout() {
        let (positions, species) = two_frames();
        let poses = Poses { positions: &positions, species: &species, fps: Some(10.0) };
        assert_eq!(poses.individuals(), ["predator_0", "prey_0", "prey_1"]);
        let bytes = poses.to_netcdf().unwrap();
        let mut reader = netcdf3::FileReader::open_seek_read("poses.nc", Box::new(Cursor::new(bytes))).unwrap();
        let position = reader.read_var_f64("position").unwrap();
        // Frame 1: x of the three, then y of the three.
        assert_eq!(&position[6..], &[1.5, 3.5, 5.5, 2.5, 4.5, 6.5]);
        assert_eq!(reader.read_var_f64("time").unwrap(), [0.0, 0.1]);
        assert_eq!(reader.read_var_u8("species").unwrap(), b"predatorprey\0\0\0\0prey\0\0\0\0");
        let set = reader.data_set();
        let dims: Vec<String> = set.get_var("position").unwrap().dim_names();
        assert_eq!(dims, ["time", "space", "keypoint", "individual"]);
        assert_eq!(set.get_global_attr_as_string("ds_type").unwrap(), "poses");
        assert_eq!(set.get_global_attr_f64("fps").unwrap(), [10.0]);
    }

    #[test]
    fn what_movement_could_not_read_is_refused() {
        let (mut positions, species) = two_frames();
        let ok = |p: &[Vec<(f64, f64)>], s: &[String], fps| Poses { positions: p, species: s, fps }.check();
        assert!(ok(&positions, &species, None).is_ok());
        assert!(ok(&positions, &species[..2], None).unwrap_err().contains("frame 0 holds 3 individuals"));
        assert!(ok(&positions, &species, Some(0.0)).unwrap_err().contains("fps 0"));
        assert!(ok(&[], &species, None).unwrap_err().contains("no frame"));
        positions[1][2].0 = f64::NAN;
        assert!(ok(&positions, &species, None).unwrap_err().contains("frame 1 holds a non-finite position"));
    }
}
