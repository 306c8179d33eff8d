//! The DBoW2 text vocabulary (`spslam::place::dbow2_text`): writer → reader
//! round trips (binary bit-exact, float exact), the header, no newline at
//! the end, parents before children, atomic writes and the reader's checks.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use spslam::place::dbow2_text::{
    parse_dbow2, read_dbow2_text, write_dbow2, write_dbow2_text, Dbow2Element,
};
use spslam::place::{
    ClusterMetric, DescriptorRows, HammingBinary, L2Float, PlaceError, SeededRng, TreeParams,
    VocabularyTree,
};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-dbow2-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn binary_tree() -> VocabularyTree<HammingBinary> {
    let mut rng = SeededRng::new(11);
    let flat: Vec<u8> = (0..300 * 32).map(|_| rng.next_u64() as u8).collect();
    let rows = DescriptorRows::from_flat(32, flat).unwrap();
    VocabularyTree::build(
        HammingBinary { bytes: 32 },
        &rows,
        &[100, 100, 50, 50],
        &TreeParams::new(5, 3),
        &mut |_| {},
    )
    .unwrap()
    .tree
}

fn float_tree(dim: usize) -> VocabularyTree<L2Float> {
    let mut rng = SeededRng::new(12);
    // Values over many magnitudes, signs and a few exact zeros.
    let flat: Vec<f32> = (0..200 * dim)
        .map(|i| {
            if i % 97 == 0 {
                0.0
            } else {
                ((rng.next_unit() - 0.5) * 10f64.powi((i % 9) as i32 - 6)) as f32
            }
        })
        .collect();
    let rows = DescriptorRows::from_flat(dim, flat).unwrap();
    VocabularyTree::build(
        L2Float { dim },
        &rows,
        &[120, 80],
        &TreeParams::new(4, 3),
        &mut |_| {},
    )
    .unwrap()
    .tree
}

/// The file's text checks common to both kinds, then a full comparison.
fn assert_round_trip<M>(tree: &VocabularyTree<M>, path: &Path, tokens_per_line: usize)
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
{
    let size = write_dbow2_text(tree, path).unwrap();
    let text = std::fs::read_to_string(path).unwrap();
    assert_eq!(size, text.len() as u64);
    assert!(!text.ends_with('\n'), "a newline after the last line");
    let lines: Vec<&str> = text.split('\n').collect();
    assert_eq!(lines[0], format!("{} {} 0 0", tree.k(), tree.depth()));
    assert_eq!(lines.len(), tree.node_count());
    for (id, line) in lines.iter().enumerate().skip(1) {
        let fields: Vec<&str> = line.split(' ').collect();
        assert_eq!(fields.len(), tokens_per_line, "line {}", id + 1);
        let parent: usize = fields[0].parse().unwrap();
        assert!(parent < id, "node {id}: parent {parent} is not before it");
        let leaf = tree.nodes()[id].is_leaf();
        assert_eq!(fields[1], if leaf { "1" } else { "0" });
        if !leaf {
            assert_eq!(fields[tokens_per_line - 1], "0");
        }
    }
    let read = read_dbow2_text(path, tree.metric().clone()).unwrap();
    assert_eq!((read.header.k, read.header.depth), (tree.k(), tree.depth()));
    assert_eq!((read.header.scoring, read.header.weighting), (0, 0));
    assert_eq!(read.tree.nodes(), tree.nodes());
    assert_eq!(read.tree.words(), tree.words());
    assert_eq!(read.tree.descriptors(), tree.descriptors());
}

#[test]
fn binary_vocabulary_round_trips_bit_exactly() {
    let dir = temp_dir("binary");
    let tree = binary_tree();
    assert_round_trip(&tree, &dir.join("voc.txt"), 2 + 32 + 1);
    // Bytes are decimal integers, as FORB::toString writes them.
    let text = std::fs::read_to_string(dir.join("voc.txt")).unwrap();
    let second = text.split('\n').nth(1).unwrap();
    for field in second.split(' ').skip(2).take(32) {
        assert!(field.parse::<u8>().is_ok(), "{field}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn float_vocabulary_round_trips_exactly() {
    let dir = temp_dir("float");
    let tree = float_tree(16);
    assert_round_trip(&tree, &dir.join("voc.txt"), 2 + 16 + 1);
    let read = read_dbow2_text(&dir.join("voc.txt"), L2Float { dim: 16 }).unwrap();
    let bits = |t: &VocabularyTree<L2Float>| -> Vec<u32> {
        t.descriptors()
            .as_flat()
            .iter()
            .map(|v| v.to_bits())
            .collect()
    };
    assert_eq!(bits(&read.tree), bits(&tree));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn writing_replaces_atomically_and_names_the_path_on_failure() {
    let dir = temp_dir("atomic");
    let path = dir.join("voc.txt");
    std::fs::write(&path, "old").unwrap();
    write_dbow2_text(&binary_tree(), &path).unwrap();
    assert!(std::fs::read_to_string(&path)
        .unwrap()
        .starts_with("5 3 0 0\n"));
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name() != "voc.txt")
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    let missing = dir.join("no/such/dir/voc.txt");
    let err = write_dbow2_text(&binary_tree(), &missing).unwrap_err();
    assert!(matches!(err, PlaceError::Io { .. }));
    assert!(
        err.to_string().contains(&missing.display().to_string()),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

fn parse_binary(text: &str) -> Result<(), PlaceError> {
    parse_dbow2(
        text.as_bytes(),
        Path::new("t.txt"),
        HammingBinary { bytes: 2 },
    )
    .map(|_| ())
}

#[test]
fn the_reader_rejects_what_orb_slam3_would_misread() {
    assert!(parse_binary("2 1 0 0\n0 1 1 2 0.5\n0 1 3 4 0.25").is_ok());
    for (text, needle) in [
        (
            "2 1 0 0\n0 1 1 2 0.5\n0 1 3 4 0.25\n",
            "ends with a newline",
        ),
        ("21 1 0 0\n0 1 1 2 0.5", "k = `21`"),
        ("2 11 0 0\n0 1 1 2 0.5", "L = `11`"),
        ("2 1 0 4\n0 1 1 2 0.5", "weighting"),
        ("2 1 0 0\n1 1 1 2 0.5", "parent `1`"),
        ("2 2 0 0\n0 1 1 2 0.5\n1 1 3 4 0.25", "parent 1 is a word"),
        ("2 1 0 0\n0 0 1 2 0", "flagged internal"),
        ("2 1 0 0\n0 1 1 256 0.5", "`256`"),
        ("2 1 0 0\n0 1 1 2", "fields"),
        ("2 1 0 0\n\n0 1 1 2 0.5", "fields"),
        (
            "2 1 0 0\n0 1 1 2 0.5\n0 1 1 2 0.5\n0 1 1 2 0.5",
            "more than k = 2",
        ),
        ("2 1 0 0\n0 0 1 2 0\n1 1 1 2 0.5", "level 2"),
        ("", "empty"),
        ("2 1 0 0", "no nodes"),
    ] {
        let err = parse_binary(text).unwrap_err();
        assert!(err.to_string().contains(needle), "{text:?}: {err}");
    }
}

#[test]
fn write_dbow2_to_memory_matches_the_file() {
    let tree = binary_tree();
    let mut bytes = Vec::new();
    let n = write_dbow2(&tree, &mut bytes).unwrap();
    assert_eq!(n, bytes.len() as u64);
    let dir = temp_dir("memory");
    write_dbow2_text(&tree, &dir.join("v.txt")).unwrap();
    assert_eq!(std::fs::read(dir.join("v.txt")).unwrap(), bytes);
    std::fs::remove_dir_all(&dir).ok();
}

proptest! {
    /// Every finite f32 (subnormals, extremes, -0) reads back bit for bit,
    /// and its text is something strtof parses: digits, sign, '.', 'e'.
    #[test]
    fn every_finite_f32_round_trips(bits in any::<u32>()) {
        let v = f32::from_bits(bits);
        let mut text = String::new();
        let written = v.write_text(&mut text);
        prop_assert_eq!(written, v.is_finite());
        if v.is_finite() {
            prop_assert!(text.chars().all(|c| c.is_ascii_digit() || "-.e".contains(c)), "{}", text);
            prop_assert_eq!(f32::parse_text(&text).map(f32::to_bits), Some(bits));
        }
    }
}
