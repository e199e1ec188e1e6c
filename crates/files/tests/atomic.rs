//! Atomic writes: the file appears whole, replaces the old one, leaves no temporary behind, and
//! a failure names the file and leaves the old contents.

use std::path::PathBuf;

use repertoire_files::{temp_sibling, write_atomic};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn a_write_replaces_the_file_whole_and_leaves_no_temporary() {
    let dir = temp("replace");
    let path = dir.join("manifest.ron");
    write_atomic(&path, b"old").unwrap();
    write_atomic(&path, b"new contents").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"new contents");
    assert_eq!(entries(&dir), ["manifest.ron"]);
}

#[test]
fn temporary_siblings_keep_the_extension_and_never_repeat() {
    let path = PathBuf::from("/x/y/plot.png");
    let (a, b) = (temp_sibling(&path), temp_sibling(&path));
    assert_ne!(a, b);
    for t in [&a, &b] {
        assert_eq!(t.parent(), path.parent());
        assert_eq!(t.extension().unwrap(), "png");
        assert!(t.file_name().unwrap().to_string_lossy().starts_with(".plot.partial-"));
    }
    let bare = temp_sibling(&PathBuf::from("/x/noext"));
    let name = bare.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with(".noext.partial-") && name.matches('.').count() == 2, "{name}");
}

#[test]
fn concurrent_writers_of_one_file_each_land_whole() {
    let dir = temp("concurrent");
    let path = dir.join("pool.ron");
    std::thread::scope(|s| {
        for k in 0..8u8 {
            let path = &path;
            s.spawn(move || {
                for _ in 0..20 {
                    write_atomic(path, &vec![k; 4096]).unwrap();
                }
            });
        }
    });
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes.len(), 4096);
    assert!(bytes.iter().all(|&b| b == bytes[0]), "two writers' bytes mixed in one file");
    assert_eq!(entries(&dir), ["pool.ron"]);
}

#[test]
fn a_failed_write_names_the_file_and_keeps_the_old_contents() {
    let dir = temp("fail");
    // A directory in the way of the rename: the write itself succeeds, the rename cannot.
    let path = dir.join("report.md");
    std::fs::create_dir(&path).unwrap();
    std::fs::write(path.join("keep"), b"x").unwrap();
    let err = write_atomic(&path, b"text").unwrap_err();
    assert!(err.to_string().contains("report.md") && err.to_string().contains("rename"), "{err}");
    assert_eq!(entries(&dir), ["report.md"], "the temporary file was left behind");
    // A missing folder: nothing can be written, and the message names the file.
    let err = write_atomic(&dir.join("missing").join("a.ron"), b"x").unwrap_err();
    assert!(err.to_string().contains("a.ron") && err.to_string().contains("cannot write"), "{err}");
}
