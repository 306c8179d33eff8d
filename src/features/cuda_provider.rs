//! ONNX Runtime's CUDA execution provider as the extractor configures it.
//!
//! cuDNN's convolution-algorithm search is the one option set here. ONNX
//! Runtime's default, `EXHAUSTIVE`, benchmarks every algorithm for a new
//! input shape, and since 1.20 again whenever one session's input shape
//! alternates between runs (onnxruntime issue #23006, "x15 slower inference
//! … pyramid images"). The extractor's pyramid does exactly that: with four
//! levels in one session, one H200 spent 490 ms per KITTI frame in the
//! network (2.9 ms with one level). `HEURISTIC` picks an algorithm from
//! cuDNN's heuristics without benchmarking, so it is the extractor's choice;
//! `SPSLAM_CUDA_CONV_SEARCH` (`heuristic`, `exhaustive` or `default`)
//! overrides it.
//!
//! `HEURISTIC` alone left the pyramid at 76 ms per frame for four levels
//! (2.6 ms for one): ONNX Runtime's CUDA convolutions also rebuild their
//! cuDNN state whenever a session's input shape changes. So on CUDA the
//! model keeps one session per input shape ([`ShapeSessions`]), each of
//! which sees one shape for the whole run. That costs GPU memory: each
//! session has its own arena, so an 8-level pyramid holds about 3.3× one
//! level's (geometric in the levels' areas); `SPSLAM_CUDA_SESSION_PER_SHAPE=0`
//! goes back to one session for a GPU that cannot hold them. The arenas
//! grow by what is requested, not by powers of two. Figures:
//! `BENCHMARKS.md`, "GPU".

use ort::ep::cuda::ConvAlgorithmSearch;
use ort::ep::ArenaExtendStrategy;
use ort::session::Session;

use super::FeatureError;

/// The environment variable that overrides cuDNN's convolution-algorithm
/// search on CUDA: `heuristic` (the extractor's default), `exhaustive`
/// (ONNX Runtime's default) or `default` (cuDNN's first algorithm).
pub const CONV_SEARCH_VARIABLE: &str = "SPSLAM_CUDA_CONV_SEARCH";

/// Parses a convolution-search name (case-insensitive).
pub fn parse_conv_search(value: &str) -> Result<ConvAlgorithmSearch, FeatureError> {
    parse_name(
        CONV_SEARCH_VARIABLE,
        value,
        &[
            ("heuristic", ConvAlgorithmSearch::Heuristic),
            ("exhaustive", ConvAlgorithmSearch::Exhaustive),
            ("default", ConvAlgorithmSearch::Default),
        ],
        "heuristic, exhaustive or default",
    )
}

/// The choice `value` names among `choices` (case-insensitive), else an
/// error naming `variable` and what it `expected`.
fn parse_name<T: Clone>(
    variable: &'static str,
    value: &str,
    choices: &[(&str, T)],
    expected: &'static str,
) -> Result<T, FeatureError> {
    let wanted = value.to_ascii_lowercase();
    choices
        .iter()
        .find(|(name, _)| *name == wanted)
        .map(|(_, choice)| choice.clone())
        .ok_or_else(|| FeatureError::InvalidConfig {
            name: variable,
            value: value.to_string(),
            expected,
        })
}

/// The search the environment asks for, else `HEURISTIC`.
pub fn conv_search_from_environment() -> Result<ConvAlgorithmSearch, FeatureError> {
    from_environment(CONV_SEARCH_VARIABLE, parse_conv_search, || {
        ConvAlgorithmSearch::Heuristic
    })
}

/// `variable` parsed by `parse` when it is set and not empty, else `default()`.
fn from_environment<T>(
    variable: &str,
    parse: impl Fn(&str) -> Result<T, FeatureError>,
    default: impl FnOnce() -> T,
) -> Result<T, FeatureError> {
    match std::env::var(variable) {
        Ok(value) if !value.is_empty() => parse(&value),
        _ => Ok(default()),
    }
}

/// The environment variable that chooses how the CUDA memory arena of each
/// session grows: `requested` (the extractor's default: by what an
/// allocation asks for) or `power-of-two` (ONNX Runtime's default: by
/// doubling chunks). On an H200, `requested` held 29 % less GPU memory with
/// eight sessions (4.0 against 5.7 GiB) at the same speed.
pub const ARENA_EXTEND_VARIABLE: &str = "SPSLAM_CUDA_ARENA_EXTEND";

/// Parses an arena-growth name (case-insensitive).
pub fn parse_arena_extend(value: &str) -> Result<ArenaExtendStrategy, FeatureError> {
    parse_name(
        ARENA_EXTEND_VARIABLE,
        value,
        &[
            ("requested", ArenaExtendStrategy::SameAsRequested),
            ("power-of-two", ArenaExtendStrategy::NextPowerOfTwo),
        ],
        "requested or power-of-two",
    )
}

/// The arena growth the environment asks for, else `requested`.
pub fn arena_extend_from_environment() -> Result<ArenaExtendStrategy, FeatureError> {
    from_environment(ARENA_EXTEND_VARIABLE, parse_arena_extend, || {
        ArenaExtendStrategy::SameAsRequested
    })
}

/// The CUDA execution provider with the extractor's options; ONNX Runtime's
/// silent fallback to the CPU is turned off (a session that cannot run on
/// CUDA is an error).
pub fn cuda_execution_provider() -> Result<ort::ep::ExecutionProviderDispatch, FeatureError> {
    Ok(ort::ep::CUDA::default()
        .with_conv_algorithm_search(conv_search_from_environment()?)
        .with_arena_extend_strategy(arena_extend_from_environment()?)
        .build()
        .error_on_failure())
}

/// The environment variable that turns the session per shape off (`0`,
/// `off` or `false`): one session serves every shape, as on the CPU, for a
/// GPU whose memory cannot hold one arena per pyramid level.
pub const SESSION_PER_SHAPE_VARIABLE: &str = "SPSLAM_CUDA_SESSION_PER_SHAPE";

/// Whether the CUDA model keeps a session per input shape: yes unless
/// [`SESSION_PER_SHAPE_VARIABLE`] says `0`, `off` or `false` (`1`, `on`,
/// `true` or unset: yes; anything else is an error naming the variable).
pub fn session_per_shape_from_environment() -> Result<bool, FeatureError> {
    from_environment(SESSION_PER_SHAPE_VARIABLE, parse_switch, || true)
}

fn parse_switch(value: &str) -> Result<bool, FeatureError> {
    parse_name(
        SESSION_PER_SHAPE_VARIABLE,
        value,
        &[
            ("1", true),
            ("on", true),
            ("true", true),
            ("0", false),
            ("off", false),
            ("false", false),
        ],
        "1, on, true, 0, off or false",
    )
}

/// At most this many input shapes keep their own CUDA session; beyond it the
/// least recently used session is dropped. An 8-level pyramid of one camera
/// needs 8; a stereo rig of two sizes 16.
pub const MAX_SHAPE_SESSIONS: usize = 16;

/// On CUDA, one ONNX Runtime session per input shape (height, width), most
/// recently used last. Each costs its own GPU memory arena (sized by its
/// shape) and a session's creation (some hundreds of milliseconds) the
/// first time its shape is seen.
pub struct ShapeSessions<S = Session> {
    sessions: Vec<((usize, usize), S)>,
}

impl<S> Default for ShapeSessions<S> {
    fn default() -> Self {
        Self {
            sessions: Vec::new(),
        }
    }
}

impl<S> ShapeSessions<S> {
    /// The session for `shape`, opened with `open` the first time the shape
    /// is seen.
    pub fn session_for(
        &mut self,
        shape: (usize, usize),
        open: impl FnOnce() -> Result<S, FeatureError>,
    ) -> Result<&mut S, FeatureError> {
        match self.sessions.iter().position(|(s, _)| *s == shape) {
            Some(at) => {
                let entry = self.sessions.remove(at);
                self.sessions.push(entry);
            }
            None => {
                let session = open()?;
                if self.sessions.len() >= MAX_SHAPE_SESSIONS {
                    self.sessions.remove(0);
                }
                self.sessions.push((shape, session));
            }
        }
        self.sessions
            .last_mut()
            .map(|(_, session)| session)
            .ok_or_else(|| FeatureError::Runtime("no CUDA session for this shape".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_search_name_parses_and_a_typo_names_the_variable() {
        for (name, expected) in [
            ("heuristic", ConvAlgorithmSearch::Heuristic),
            ("EXHAUSTIVE", ConvAlgorithmSearch::Exhaustive),
            ("Default", ConvAlgorithmSearch::Default),
        ] {
            let parsed = parse_conv_search(name).map_err(|e| e.to_string());
            assert_eq!(
                format!("{parsed:?}"),
                format!("{:?}", Ok::<_, String>(expected))
            );
        }
        let err = parse_conv_search("heuristics").err().map(|e| e.to_string());
        assert!(err
            .is_some_and(|e| e.contains(CONV_SEARCH_VARIABLE)
                && e.contains("heuristic, exhaustive or default")));
    }

    #[test]
    fn both_arena_growths_parse_and_a_typo_names_the_variable() {
        let name = |value: &str| parse_arena_extend(value).map(|s| s.to_string()).ok();
        assert_eq!(name("Requested").as_deref(), Some("kSameAsRequested"));
        assert_eq!(name("power-of-two").as_deref(), Some("kNextPowerOfTwo"));
        let err = parse_arena_extend("same").err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains(ARENA_EXTEND_VARIABLE)));
    }

    #[test]
    fn the_session_per_shape_switch_parses_and_a_typo_names_the_variable() {
        for (value, expected) in [
            ("1", true),
            ("ON", true),
            ("true", true),
            ("0", false),
            ("Off", false),
            ("false", false),
        ] {
            assert_eq!(parse_switch(value).ok(), Some(expected), "{value}");
        }
        let err = parse_switch("no").err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains(SESSION_PER_SHAPE_VARIABLE)));
    }

    #[test]
    fn each_shape_opens_once_and_the_least_recently_used_is_dropped_beyond_the_cap() {
        let mut sessions = ShapeSessions::<usize>::default();
        let mut opened = 0;
        let mut open = |sessions: &mut ShapeSessions<usize>, shape: (usize, usize)| {
            *sessions
                .session_for(shape, || {
                    opened += 1;
                    Ok(opened)
                })
                .map_err(|e| e.to_string())
                .as_deref()
                .unwrap_or(&0)
        };
        // An 8-level pyramid, two frames: eight sessions, opened on the first.
        let levels: Vec<(usize, usize)> = (0..8).map(|l| (376 - 40 * l, 1232 - 120 * l)).collect();
        let first: Vec<usize> = levels.iter().map(|&s| open(&mut sessions, s)).collect();
        let second: Vec<usize> = levels.iter().map(|&s| open(&mut sessions, s)).collect();
        assert_eq!(first, (1..=8).collect::<Vec<_>>());
        assert_eq!(second, first);
        // Past the cap, the least recently used shape (level 0) goes first.
        for extra in 0..MAX_SHAPE_SESSIONS - 8 {
            open(&mut sessions, (8, 8 * (extra + 1)));
        }
        assert_eq!(open(&mut sessions, levels[1]), 2);
        open(&mut sessions, (9, 9));
        assert_eq!(open(&mut sessions, levels[0]), MAX_SHAPE_SESSIONS + 2);
    }
}
