//! `spslam vocab train` end to end: small float and binary vocabularies from
//! the KITTI excerpt, read back with the library's reader; and its errors.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use spslam::place::dbow2_text::read_dbow2_text;
use spslam::place::{ClusterMetric, HammingBinary, L2Float};

fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-cli-vocab-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn vocab_train(images: &Path, out: &Path, args: &[&str]) -> Output {
    spslam()
        .args(["vocab", "train", "--images"])
        .arg(images)
        .arg("--out")
        .arg(out)
        .args(args)
        .output()
        .unwrap()
}

/// k = 5, L = 3 on 6 images with 300 keypoints each, plus `extra`.
fn train(images: &Path, out: &Path, extra: &[&str]) -> Output {
    let small = [
        "--k",
        "5",
        "--depth",
        "3",
        "--max-images",
        "6",
        "--features",
        "300",
    ];
    vocab_train(images, out, &[&small[..], extra].concat())
}

fn assert_success(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The file parses, its header is `5 3 0 0`, it has no newline at the end,
/// and its node and word counts are the ones printed and within k and L.
fn check_vocabulary<M: ClusterMetric>(path: &Path, metric: M, stdout: &str, descriptors: &str)
where
    M::Elem: spslam::place::dbow2_text::Dbow2Element,
{
    let bytes = std::fs::read(path).unwrap();
    assert!(bytes.starts_with(b"5 3 0 0\n"));
    assert_ne!(bytes.last(), Some(&b'\n'), "newline after the last line");
    let voc = read_dbow2_text(path, metric).unwrap();
    let tree = &voc.tree;
    assert_eq!((voc.header.k, voc.header.depth), (5, 3));
    assert!(tree.node_count() <= 1 + 5 + 25 + 125);
    assert!(tree.word_count() > 25, "{} words", tree.word_count());
    let lines = bytes.iter().filter(|&&b| b == b'\n').count() + 1;
    assert_eq!(lines, tree.node_count());
    assert!(
        stdout.contains(&format!(
            "{} nodes, {} words",
            tree.node_count(),
            tree.word_count()
        )),
        "{stdout}"
    );
    assert!(
        stdout.contains(&format!("images: 6, descriptors: {descriptors}")),
        "{stdout}"
    );
    assert!(tree.nodes().iter().any(|n| n.weight > 0.0));
}

#[test]
fn trains_float_and_binary_vocabularies_from_kitti() {
    let Some(data) = common::setup("trains_float_and_binary_vocabularies_from_kitti") else {
        return;
    };
    let images = data.join("kitti/sequences/06/image_0");
    let dir = temp_dir("train");
    let float = dir.join("float.txt");
    let stdout = assert_success(&train(&images, &float, &[]));
    assert!(stdout.contains("float[256] (L2)"), "{stdout}");
    check_vocabulary(&float, L2Float { dim: 256 }, &stdout, "1800 ");

    let binary = dir.join("binary.txt");
    let stdout = assert_success(&train(&images, &binary, &["--descriptors", "binary"]));
    assert!(stdout.contains("binary[32 bytes] (Hamming)"), "{stdout}");
    check_vocabulary(&binary, HammingBinary { bytes: 32 }, &stdout, "1800 ");

    // The same seed gives the same file; another seed, another one.
    let again = dir.join("binary_again.txt");
    assert_success(&train(&images, &again, &["--descriptors", "binary"]));
    assert_eq!(
        std::fs::read(&binary).unwrap(),
        std::fs::read(&again).unwrap()
    );
    let other = dir.join("binary_seed.txt");
    assert_success(&train(
        &images,
        &other,
        &["--descriptors", "binary", "--seed", "5"],
    ));
    assert_ne!(
        std::fs::read(&binary).unwrap(),
        std::fs::read(&other).unwrap()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn trains_an_orb_vocabulary_from_kitti() {
    let Some(data) = common::data_dir("trains_an_orb_vocabulary_from_kitti") else {
        return;
    };
    let dir = temp_dir("orb");
    let out = dir.join("orb.txt");
    let stdout = assert_success(&train(
        &data.join("kitti/sequences/06/image_0"),
        &out,
        &["--descriptors", "orb"],
    ));
    assert!(stdout.contains("extractor: orb (8 levels)"), "{stdout}");
    // ORB-SLAM3's octree keeps about, not exactly, 300 keypoints per image.
    check_vocabulary(&out, HammingBinary { bytes: 32 }, &stdout, "");
    std::fs::remove_dir_all(&dir).ok();
}

fn assert_fails_with(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains(needle), "expected `{needle}` in: {stderr}");
}

#[test]
fn bad_input_fails_with_a_message_naming_it() {
    let dir = temp_dir("errors");
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    std::fs::write(images.join("broken.png"), b"not a png").unwrap();
    let out = dir.join("voc.txt");
    // ORB needs no model: the unreadable image is reported by name.
    assert_fails_with(
        &train(&images, &out, &["--descriptors", "orb"]),
        "broken.png",
    );
    assert_fails_with(
        &vocab_train(&images, &out, &["--k", "21"]),
        "k (branching factor) = 21",
    );
    assert_fails_with(
        &vocab_train(&images, &out, &["--depth", "11"]),
        "L (depth) = 11",
    );
    assert_fails_with(
        &vocab_train(&images, &out, &["--settings", "x.yaml", "--features", "5"]),
        "cannot be used with",
    );
    assert_fails_with(&train(&dir.join("nowhere"), &out, &[]), "nowhere");
    assert_fails_with(
        &train(&images, &dir.join("no/such/voc.txt"), &[]),
        "does not exist",
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).ok();
}
