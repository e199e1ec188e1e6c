//! What a recipe keeps in `{work}/.recipe`: one record per stage (`stages/*.ron`: identity,
//! status, what it wrote by content hash) and the content itself (`objects/ab/cdef…`), so a
//! stage that runs again can be given exactly what the stages before it left.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::{Result, io_err};

/// The SHA-256 of a file's bytes, hex.
pub fn hash_file(path: &Path) -> Result<String> {
    let mut f = std::fs::File::open(path).map_err(io_err(path, "cannot read"))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf).map_err(io_err(path, "cannot read"))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(hex(&h.finalize()))
}

/// The hash of a file, or of a folder: every file under it, by relative path and content.
pub fn hash_path(path: &Path) -> Result<String> {
    let meta = std::fs::metadata(path).map_err(io_err(path, "cannot read"))?;
    if meta.is_file() {
        return hash_file(path);
    }
    let mut h = Sha256::new();
    for (rel, file) in files_under(path)? {
        h.update(rel.as_bytes());
        h.update([0]);
        h.update(hash_file(&file)?.as_bytes());
        h.update([0]);
    }
    Ok(hex(&h.finalize()))
}

/// Every file under `root` (itself when it is a file), with its path relative to `root` using
/// `/`, sorted. A missing root has none.
pub fn files_under(root: &Path) -> Result<Vec<(String, PathBuf)>> {
    let mut out = Vec::new();
    if !root.exists() {
        return Ok(out);
    }
    if root.is_file() {
        out.push((String::new(), root.to_path_buf()));
        return Ok(out);
    }
    let mut todo = vec![root.to_path_buf()];
    while let Some(dir) = todo.pop() {
        for entry in std::fs::read_dir(&dir).map_err(io_err(&dir, "cannot list"))? {
            let entry = entry.map_err(io_err(&dir, "cannot list"))?;
            let p = entry.path();
            let kind = entry.file_type().map_err(io_err(&p, "cannot read"))?;
            if kind.is_dir() {
                todo.push(p);
            } else if kind.is_file() {
                let rel = p.strip_prefix(root).expect("under root").components();
                let rel = rel.map(|c| c.as_os_str().to_string_lossy().into_owned()).collect::<Vec<_>>().join("/");
                out.push((rel, p));
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Where a stage stands.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Status {
    /// Handed to Slurm as this job.
    Queued { job: u64 },
    /// Started (and not finished: running, or interrupted).
    Started,
    /// Finished.
    Done,
}

/// What is known of one stage (`{work}/.recipe/stages/ID.ron`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Record {
    /// The stage.
    pub id: String,
    /// The identity it ran (or runs) with.
    pub identity: String,
    /// Where it stands.
    pub status: Status,
    /// What it wrote: path (relative to the folder the recipe runs in) → content hash.
    #[serde(default)]
    pub outputs: BTreeMap<String, String>,
    /// The command (`repertoire …`, or `copy FROM TO`).
    pub command: String,
    /// Seconds it took (0 until done).
    #[serde(default)]
    pub seconds: f64,
    /// Where it ran (`local` or `slurm job N`).
    #[serde(default)]
    pub ran: String,
    /// The identities it had before `recipe adopt` kept what it made for the current inputs,
    /// oldest first (none for a stage that ran with its identity).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub adopted: Vec<String>,
}

/// A recipe's store under `dir` (`{work}/.recipe`).
#[derive(Debug, Clone)]
pub struct Store {
    dir: PathBuf,
}

impl Store {
    /// The store in `dir`.
    pub fn new(dir: PathBuf) -> Store {
        Store { dir }
    }

    fn record_path(&self, id: &str) -> PathBuf {
        self.dir.join("stages").join(format!("{}.ron", id.replace('/', "~")))
    }

    /// The folder of Slurm job logs.
    pub fn log_dir(&self) -> PathBuf {
        self.dir.join("logs")
    }

    /// The record of stage `id`, if there is one.
    pub fn record(&self, id: &str) -> Result<Option<Record>> {
        let path = self.record_path(id);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(io_err(&path, "cannot read"))?;
        ron::from_str(&text).map(Some).map_err(|e| crate::RecipeError::Parse {
            path: path.display().to_string(),
            line: e.span.start.line,
            col: e.span.start.col,
            message: format!("{} (delete it to run the stage again)", e.code),
        })
    }

    /// Writes `record` (atomically).
    pub fn put(&self, record: &Record) -> Result<()> {
        let path = self.record_path(&record.id);
        let parent = path.parent().expect("stages/");
        std::fs::create_dir_all(parent).map_err(io_err(parent, "cannot create"))?;
        let text = ron::ser::to_string_pretty(record, ron::ser::PrettyConfig::default()).expect("records serialise");
        repertoire_files::write_atomic(&path, text.as_bytes()).map_err(|e| crate::RecipeError::Io {
            path: e.path.display().to_string(),
            message: e.action,
            source: e.source,
        })
    }

    fn object(&self, hash: &str) -> PathBuf {
        self.dir.join("objects").join(&hash[..2]).join(&hash[2..])
    }

    /// Keeps every file under `roots` by content; returns path → hash.
    pub fn keep(&self, roots: &[PathBuf]) -> Result<BTreeMap<String, String>> {
        let mut out = BTreeMap::new();
        for root in roots {
            for (_, file) in files_under(root)? {
                let hash = hash_file(&file)?;
                let obj = self.object(&hash);
                if !obj.exists() {
                    let parent = obj.parent().expect("objects/ab");
                    std::fs::create_dir_all(parent).map_err(io_err(parent, "cannot create"))?;
                    let tmp = repertoire_files::temp_sibling(&obj);
                    std::fs::copy(&file, &tmp).map_err(io_err(&file, "cannot keep a copy"))?;
                    repertoire_files::commit(&tmp, &obj).map_err(|e| crate::RecipeError::Io {
                        path: e.path.display().to_string(),
                        message: e.action,
                        source: e.source,
                    })?;
                }
                out.insert(file.to_string_lossy().replace('\\', "/"), hash);
            }
        }
        Ok(out)
    }

    /// Makes the files of `expected` (path → hash) hold that content again, copying it from
    /// the store where they differ; returns how many it restored.
    pub fn restore(&self, expected: &BTreeMap<String, String>) -> Result<usize> {
        let mut n = 0;
        for (path, hash) in expected {
            let path = Path::new(path);
            if path.is_file() && &hash_file(path)? == hash {
                continue;
            }
            let obj = self.object(hash);
            if !obj.exists() {
                return Err(crate::RecipeError::Invalid {
                    path: obj.display().to_string(),
                    message: format!(
                        "the kept content of {} is gone; delete the records under {} to run the recipe afresh",
                        path.display(),
                        self.dir.join("stages").display()
                    ),
                });
            }
            if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
                std::fs::create_dir_all(parent).map_err(io_err(parent, "cannot create"))?;
            }
            let tmp = repertoire_files::temp_sibling(path);
            std::fs::copy(&obj, &tmp).map_err(io_err(&obj, "cannot restore"))?;
            repertoire_files::commit(&tmp, path).map_err(|e| crate::RecipeError::Io {
                path: e.path.display().to_string(),
                message: e.action,
                source: e.source,
            })?;
            n += 1;
        }
        Ok(n)
    }
}
