//! The DBoW2 text vocabulary format, as ORB-SLAM3's
//! `TemplatedVocabulary::saveToTextFile` writes it and `loadFromTextFile`
//! reads it:
//!
//! ```text
//! k L scoring weighting
//! parent_id is_leaf d_1 ... d_D weight
//! ...
//! ```
//!
//! - the header here is always `k L 0 0`: L1-norm scoring, TF-IDF weighting;
//! - one line per node except the root, in node order (ids 1, 2, ...; a
//!   parent's line comes before its children's): `is_leaf` is 1 for a word,
//!   0 otherwise, and `weight` is 0 for internal nodes;
//! - binary descriptors are written a byte at a time as decimal integers
//!   0..255 (`FORB::toString`); float descriptors as `f32` numbers in
//!   scientific notation with the fewest digits that read back to the same
//!   `f32` (`strtof` and `std::istream` parse them);
//! - **no newline after the last line**: ORB-SLAM3's loader loops on
//!   `!f.eof()` and would read a trailing newline as one more, empty node.
//!
//! The loader's header check, mirrored by the reader: `0 <= k <= 20`,
//! `1 <= L <= 10`, `0 <= scoring <= 5`, `0 <= weighting <= 3`.

use std::fmt::Write as _;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::{ClusterMetric, DescriptorRows, PlaceError, TreeNode, VocabularyTree};

/// DBoW2's `ScoringType::L1_NORM`.
pub const SCORING_L1_NORM: u8 = 0;
/// DBoW2's `WeightingType::TF_IDF`.
pub const WEIGHTING_TF_IDF: u8 = 0;

/// A descriptor value as the text format writes and reads it.
pub trait Dbow2Element: Copy {
    /// Appends the value's text to `out`; false when it cannot be written
    /// (a NaN or an infinity).
    fn write_text(self, out: &mut String) -> bool;
    /// Parses one token; `None` when it is not a valid value.
    fn parse_text(token: &str) -> Option<Self>;
}

impl Dbow2Element for u8 {
    fn write_text(self, out: &mut String) -> bool {
        // Writing to a String cannot fail.
        let _ = write!(out, "{self}");
        true
    }

    fn parse_text(token: &str) -> Option<Self> {
        token.parse().ok()
    }
}

impl Dbow2Element for f32 {
    fn write_text(self, out: &mut String) -> bool {
        if !self.is_finite() {
            return false;
        }
        // `{:e}` is Rust's shortest round-trip form, e.g. `-6.2500002e-2`.
        let _ = write!(out, "{self:e}");
        true
    }

    fn parse_text(token: &str) -> Option<Self> {
        token.parse::<f32>().ok().filter(|v| v.is_finite())
    }
}

/// The four numbers of the first line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dbow2Header {
    /// Branching factor.
    pub k: usize,
    /// Depth levels.
    pub depth: usize,
    /// DBoW2's `ScoringType` (0 = L1-norm).
    pub scoring: u8,
    /// DBoW2's `WeightingType` (0 = TF-IDF).
    pub weighting: u8,
}

/// A vocabulary read from a text file.
#[derive(Debug, Clone)]
pub struct Dbow2Vocabulary<M: ClusterMetric> {
    /// The header line.
    pub header: Dbow2Header,
    /// The tree, its nodes in file order.
    pub tree: VocabularyTree<M>,
}

/// Writes `tree` to `out` in the text format (no newline after the last
/// line); returns the bytes written.
pub fn write_dbow2<M, W>(tree: &VocabularyTree<M>, out: &mut W) -> Result<u64, PlaceError>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
    W: Write,
{
    let io = |source| PlaceError::Io {
        action: "write",
        path: PathBuf::from("<stream>"),
        source,
    };
    let header = format!(
        "{} {} {SCORING_L1_NORM} {WEIGHTING_TF_IDF}",
        tree.k(),
        tree.depth()
    );
    out.write_all(header.as_bytes()).map_err(io)?;
    let mut written = header.len() as u64;
    let mut line = String::new();
    for (id, node) in tree.nodes().iter().enumerate().skip(1) {
        line.clear();
        let _ = write!(line, "\n{} {}", node.parent, u8::from(node.is_leaf()));
        for &v in tree.descriptor(id) {
            line.push(' ');
            if !v.write_text(&mut line) {
                return Err(PlaceError::NonFinite { node: id });
            }
        }
        let weight = if node.is_leaf() { node.weight } else { 0.0 };
        let _ = write!(line, " {weight}");
        out.write_all(line.as_bytes()).map_err(io)?;
        written += line.len() as u64;
    }
    Ok(written)
}

/// Writes `tree` to `path` atomically: into a temporary file beside it,
/// synced, then renamed over `path`. Returns the file's size in bytes.
pub fn write_dbow2_text<M>(tree: &VocabularyTree<M>, path: &Path) -> Result<u64, PlaceError>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
{
    let name = path.file_name().ok_or_else(|| PlaceError::Io {
        action: "write",
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name"),
    })?;
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".tmp{}", std::process::id()));
    let temp = path.with_file_name(temp_name);
    let result = write_file(tree, path, &temp);
    if result.is_err() {
        // The temporary file may not exist; nothing more to report then.
        let _ = std::fs::remove_file(&temp);
    }
    result
}

fn write_file<M>(tree: &VocabularyTree<M>, path: &Path, temp: &Path) -> Result<u64, PlaceError>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
{
    let io = |action, source| PlaceError::Io {
        action,
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::create(temp).map_err(|e| io("create", e))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    let written = write_dbow2(tree, &mut out).map_err(|e| match e {
        PlaceError::Io { source, .. } => io("write", source),
        other => other,
    })?;
    let file = out.into_inner().map_err(|e| io("write", e.into_error()))?;
    file.sync_all().map_err(|e| io("write", e))?;
    drop(file);
    std::fs::rename(temp, path).map_err(|e| io("rename a temporary file onto", e))?;
    Ok(written)
}

/// Reads a text vocabulary whose descriptors are rows of `metric`, checking
/// what ORB-SLAM3's loader assumes: the header's ranges, each parent before
/// its children and not a word, the leaf flags, at most k children, at most
/// L levels, and no newline after the last line.
pub fn read_dbow2_text<M>(path: &Path, metric: M) -> Result<Dbow2Vocabulary<M>, PlaceError>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
{
    let file = std::fs::File::open(path).map_err(|source| PlaceError::Io {
        action: "read",
        path: path.to_path_buf(),
        source,
    })?;
    parse_dbow2(BufReader::new(file), path, metric)
}

/// [`read_dbow2_text`] on any reader; `path` names it in errors.
pub fn parse_dbow2<M, R>(
    mut reader: R,
    path: &Path,
    metric: M,
) -> Result<Dbow2Vocabulary<M>, PlaceError>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
    R: BufRead,
{
    let fail = |line: usize, reason: String| PlaceError::Parse {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut buf = String::new();
    let mut read_line = |buf: &mut String, line: usize| {
        buf.clear();
        reader
            .read_line(buf)
            .map_err(|e| fail(line, format!("cannot read: {e}")))
    };
    if read_line(&mut buf, 1)? == 0 {
        return Err(fail(1, "the file is empty".into()));
    }
    let mut ends_with_newline = buf.ends_with('\n');
    let header = parse_header(&buf).map_err(|reason| fail(1, reason))?;
    let d = metric.row_len();
    let mut nodes = vec![TreeNode {
        parent: 0,
        children: Vec::new(),
        weight: 0.0,
        word: None,
    }];
    let mut leaf_flags = vec![false];
    let mut levels = vec![0usize];
    let mut descriptors = DescriptorRows::new(d)?;
    descriptors.push_row(&vec![M::Elem::default(); d])?;
    let mut row = Vec::with_capacity(d);
    let mut line_no = 1;
    loop {
        line_no += 1;
        if read_line(&mut buf, line_no)? == 0 {
            break;
        }
        ends_with_newline = buf.ends_with('\n');
        let id = nodes.len();
        let tokens: Vec<&str> = buf.split_ascii_whitespace().collect();
        if tokens.len() != d + 3 {
            return Err(fail(
                line_no,
                format!(
                    "{} fields; a node line has parent, leaf flag, {d} descriptor values and weight ({} fields)",
                    tokens.len(),
                    d + 3
                ),
            ));
        }
        let parent: usize = tokens[0].parse().ok().filter(|&p| p < id).ok_or_else(|| {
            fail(
                line_no,
                format!(
                    "parent `{}` is not an earlier node's id (0..{id})",
                    tokens[0]
                ),
            )
        })?;
        if leaf_flags[parent] {
            return Err(fail(line_no, format!("parent {parent} is a word (leaf)")));
        }
        let is_leaf = match tokens[1] {
            "0" => false,
            "1" => true,
            other => return Err(fail(line_no, format!("leaf flag `{other}` is not 0 or 1"))),
        };
        row.clear();
        for token in &tokens[2..2 + d] {
            row.push(
                M::Elem::parse_text(token)
                    .ok_or_else(|| fail(line_no, format!("`{token}` is not a descriptor value")))?,
            );
        }
        let weight: f64 = tokens[d + 2]
            .parse()
            .ok()
            .filter(|w: &f64| w.is_finite())
            .ok_or_else(|| {
                fail(
                    line_no,
                    format!("weight `{}` is not a number", tokens[d + 2]),
                )
            })?;
        let level = levels[parent] + 1;
        if level > header.depth {
            return Err(fail(
                line_no,
                format!(
                    "node {id} is on level {level}, below the depth L = {}",
                    header.depth
                ),
            ));
        }
        nodes[parent].children.push(id as u32);
        if nodes[parent].children.len() > header.k {
            return Err(fail(
                line_no,
                format!("node {parent} has more than k = {} children", header.k),
            ));
        }
        nodes.push(TreeNode {
            parent: parent as u32,
            children: Vec::new(),
            weight,
            word: None,
        });
        leaf_flags.push(is_leaf);
        levels.push(level);
        descriptors.push_row(&row)?;
    }
    if ends_with_newline {
        return Err(fail(
            line_no,
            "the file ends with a newline: ORB-SLAM3's loader would read it as one more, empty node"
                .into(),
        ));
    }
    if nodes.len() == 1 {
        return Err(fail(2, "the vocabulary has no nodes".into()));
    }
    for (id, (node, &leaf)) in nodes.iter().zip(&leaf_flags).enumerate().skip(1) {
        if leaf != node.is_leaf() {
            let reason = if leaf {
                "is flagged a word but has children"
            } else {
                "is flagged internal but has no children"
            };
            return Err(fail(id + 1, format!("node {id} {reason}")));
        }
    }
    let tree = VocabularyTree::from_parts(metric, header.k, header.depth, nodes, descriptors);
    Ok(Dbow2Vocabulary { header, tree })
}

/// `k L scoring weighting`, within ORB-SLAM3's loader's ranges.
fn parse_header(line: &str) -> Result<Dbow2Header, String> {
    let fields: Vec<&str> = line.split_ascii_whitespace().collect();
    if fields.len() != 4 {
        return Err(format!(
            "the header `{}` is not `k L scoring weighting`",
            line.trim_end()
        ));
    }
    let number = |i: usize, name: &str, max: usize, min: usize| -> Result<usize, String> {
        fields[i]
            .parse::<usize>()
            .ok()
            .filter(|v| (min..=max).contains(v))
            .ok_or_else(|| {
                format!(
                    "header {name} = `{}` is outside {min}..={max} (ORB-SLAM3's loader's limits)",
                    fields[i]
                )
            })
    };
    Ok(Dbow2Header {
        k: number(0, "k", 20, 0)?,
        depth: number(1, "L", 10, 1)?,
        scoring: number(2, "scoring", 5, 0)? as u8,
        weighting: number(3, "weighting", 3, 0)? as u8,
    })
}
