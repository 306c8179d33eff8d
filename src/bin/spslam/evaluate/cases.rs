//! The case list of `spslam evaluate` (`suite/cases.txt`): synthetic scenes
//! and the runs made on them and on the real datasets.
//!
//! One entry per line, words separated by blanks, `#` starts a comment:
//!
//! ```text
//! scene NAME SYNTH-ARGUMENTS...
//! case  NAME GROUP SETS DATASET RUN-ARGUMENTS...
//! place NAME SETS DATASET LOOPS-ARGUMENTS...
//! ```
//!
//! A `scene` is written once by `spslam synth --out OUT/scenes/NAME
//! SYNTH-ARGUMENTS`. A `case` is one `spslam run --dataset DATASET
//! RUN-ARGUMENTS`; GROUP names the runs compared with each other (same data,
//! same sensor, same condition: the extractors side by side) and SETS the
//! comma-separated sets the case belongs to (`quick`, `standard`, ...). In
//! DATASET, `$DATA` stands for the shared data folder and `@NAME` for the
//! folder of scene NAME. A `place` is one `spslam loops --dataset DATASET
//! LOOPS-ARGUMENTS`: place recognition judged against the ground truth,
//! whose precision–recall curves the summary gathers.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A mistake in the case list, with the line it is on.
#[derive(Debug, thiserror::Error)]
pub enum CaseListError {
    /// The file cannot be read.
    #[error("cannot read the case list {path}: {source}")]
    Read {
        /// The case list.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A line is not `scene ...` or `case ...` with enough words.
    #[error("{path}:{line}: {what}")]
    Syntax {
        /// The case list.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong there.
        what: String,
    },
}

/// A synthetic sequence of the suite.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Scene {
    /// Its name: the folder under OUT/scenes and `@NAME` in datasets.
    pub name: String,
    /// `spslam synth`'s arguments (without `--out`).
    pub synth_args: Vec<String>,
}

/// Which subcommand a case runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaseTool {
    /// `spslam run`: SLAM over the sequence (a `case` line).
    Run,
    /// `spslam loops`: place recognition judged against the ground truth
    /// (a `place` line).
    Loops,
}

/// One run of the suite.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Case {
    /// The subcommand it runs.
    pub tool: CaseTool,
    /// Its name: the folder under OUT/runs.
    pub name: String,
    /// The runs compared with each other in the summary.
    pub group: String,
    /// The sets it belongs to.
    pub sets: Vec<String>,
    /// `spslam run --dataset` as written (with `$DATA` and `@SCENE`).
    pub dataset: String,
    /// The subcommand's other arguments.
    pub run_args: Vec<String>,
    /// The scene its dataset names, if any.
    pub scene: Option<String>,
}

/// What the words `$DATA`, `$SUITE` and `@SCENE` stand for in a case.
pub struct Substitutions {
    /// The shared data folder (`$DATA`).
    pub data: PathBuf,
    /// The case list's folder (`$SUITE`), for files kept beside it.
    pub suite: PathBuf,
    /// The folder of the scenes (`@NAME` is its subfolder NAME).
    pub scenes: PathBuf,
}

impl Substitutions {
    fn apply(&self, word: &str, scene: Option<&str>) -> String {
        let mut word = word
            .replace("$DATA", &self.data.to_string_lossy())
            .replace("$SUITE", &self.suite.to_string_lossy());
        if let Some(scene) = scene {
            let folder = self.scenes.join(scene);
            word = word.replace(&format!("@{scene}"), &folder.to_string_lossy());
        }
        word
    }
}

impl Case {
    /// The dataset argument with `$DATA`, `$SUITE` and `@SCENE` replaced.
    pub fn resolved_dataset(&self, subs: &Substitutions) -> String {
        subs.apply(&self.dataset, self.scene.as_deref())
    }

    /// `spslam run`'s other arguments with `$DATA` and `$SUITE` replaced.
    pub fn resolved_args(&self, subs: &Substitutions) -> Vec<String> {
        self.run_args.iter().map(|a| subs.apply(a, None)).collect()
    }
}

/// The parsed case list.
#[derive(Debug, Clone, Default)]
pub struct CaseList {
    /// Scenes by name.
    pub scenes: BTreeMap<String, Scene>,
    /// Cases in file order.
    pub cases: Vec<Case>,
}

/// The scene a dataset names with `@NAME` (up to the next `/`).
fn scene_of(dataset: &str) -> Option<String> {
    let (_, after) = dataset.split_once('@')?;
    let name: String = after.chars().take_while(|c| *c != '/').collect();
    Some(name)
}

/// Names are folder names: letters, digits, `_`, `-`, `.`.
fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

impl CaseList {
    /// Reads and checks a case list file.
    pub fn read(path: &Path) -> Result<Self, CaseListError> {
        let text = std::fs::read_to_string(path).map_err(|source| CaseListError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses a case list; `path` only names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, CaseListError> {
        let mut list = CaseList::default();
        for (index, raw) in text.lines().enumerate() {
            let syntax = |what: String| CaseListError::Syntax {
                path: path.to_path_buf(),
                line: index + 1,
                what,
            };
            let line = raw.split('#').next().unwrap_or("");
            let words: Vec<String> = line.split_whitespace().map(str::to_owned).collect();
            let Some(kind) = words.first() else { continue };
            match kind.as_str() {
                "scene" => {
                    let [_, name, args @ ..] = words.as_slice() else {
                        return Err(syntax(
                            "`scene` needs a NAME and spslam synth's arguments".into(),
                        ));
                    };
                    if !valid_name(name) {
                        return Err(syntax(format!(
                            "`{name}` is not a valid scene name (letters, digits, _ - .)"
                        )));
                    }
                    if args.iter().any(|a| a == "--out") {
                        return Err(syntax(
                            "a scene's arguments must not set --out: the suite chooses it".into(),
                        ));
                    }
                    let scene = Scene {
                        name: name.clone(),
                        synth_args: args.to_vec(),
                    };
                    if list.scenes.insert(name.clone(), scene).is_some() {
                        return Err(syntax(format!("scene `{name}` is defined twice")));
                    }
                }
                "case" => {
                    let [_, name, group, sets, dataset, args @ ..] = words.as_slice() else {
                        return Err(syntax(
                            "`case` needs NAME GROUP SETS DATASET [spslam run's arguments]".into(),
                        ));
                    };
                    if !valid_name(name) {
                        return Err(syntax(format!(
                            "`{name}` is not a valid case name (letters, digits, _ - .)"
                        )));
                    }
                    let has = |flag: &str| {
                        args.iter()
                            .any(|a| a == flag || a.starts_with(&format!("{flag}=")))
                    };
                    if let Some(bad) = ["--out", "--dataset", "--inline-mapping"]
                        .into_iter()
                        .find(|flag| has(flag))
                    {
                        return Err(syntax(format!(
                            "a case's arguments must not set {bad}: the suite chooses it \
                             (mapping runs inline unless the case says --mapping-thread)"
                        )));
                    }
                    if has("--mapping-slowdown") && !has("--mapping-thread") {
                        return Err(syntax(
                            "--mapping-slowdown needs --mapping-thread in the same case".into(),
                        ));
                    }
                    if name.ends_with(".log") || name.ends_with(".case.json") {
                        return Err(syntax(format!(
                            "`{name}` ends like the suite's own files (.log, .case.json)"
                        )));
                    }
                    list.add_case(CaseTool::Run, name, group, sets, dataset, args)
                        .map_err(syntax)?;
                }
                "place" => {
                    let [_, name, sets, dataset, args @ ..] = words.as_slice() else {
                        return Err(syntax(
                            "`place` needs NAME SETS DATASET [spslam loops's arguments]".into(),
                        ));
                    };
                    if !valid_name(name) || name.ends_with(".log") || name.ends_with(".case.json") {
                        return Err(syntax(format!(
                            "`{name}` is not a valid case name (letters, digits, _ - ., not ending in .log or .case.json)"
                        )));
                    }
                    if let Some(bad) =
                        ["--dataset", "--images", "--curves"]
                            .into_iter()
                            .find(|flag| {
                                args.iter()
                                    .any(|a| a == flag || a.starts_with(&format!("{flag}=")))
                            })
                    {
                        return Err(syntax(format!(
                            "a place case's arguments must not set {bad}: the suite chooses it"
                        )));
                    }
                    list.add_case(CaseTool::Loops, name, "place", sets, dataset, args)
                        .map_err(syntax)?;
                }
                other => {
                    return Err(syntax(format!(
                        "a line starts with `scene`, `case` or `place`, not `{other}`"
                    )))
                }
            }
        }
        Ok(list)
    }

    /// Adds a case after checking that its name is new and its scene is
    /// defined; the error says what is wrong.
    fn add_case(
        &mut self,
        tool: CaseTool,
        name: &str,
        group: &str,
        sets: &str,
        dataset: &str,
        args: &[String],
    ) -> Result<(), String> {
        if self.cases.iter().any(|c| c.name == name) {
            return Err(format!("case `{name}` is defined twice"));
        }
        let scene = scene_of(dataset);
        if let Some(scene) = &scene {
            if !self.scenes.contains_key(scene) {
                return Err(format!(
                    "case `{name}` uses scene `@{scene}`, which is not defined above it"
                ));
            }
        }
        self.cases.push(Case {
            tool,
            name: name.to_owned(),
            group: group.to_owned(),
            sets: sets
                .split(',')
                .filter(|s| !s.is_empty())
                .map(str::to_owned)
                .collect(),
            dataset: dataset.to_owned(),
            run_args: args.to_vec(),
            scene,
        });
        Ok(())
    }

    /// The cases of `set` (every case for `all`), or the named ones.
    pub fn select(&self, set: &str, names: &[String]) -> Result<Vec<&Case>, String> {
        if !names.is_empty() {
            let mut unique: Vec<&String> = Vec::new();
            for name in names {
                if !unique.contains(&name) {
                    unique.push(name);
                }
            }
            return unique
                .into_iter()
                .map(|n| {
                    self.cases
                        .iter()
                        .find(|c| &c.name == n)
                        .ok_or_else(|| format!("no case named `{n}` in the case list"))
                })
                .collect();
        }
        let chosen: Vec<&Case> = self
            .cases
            .iter()
            .filter(|c| set == "all" || c.sets.iter().any(|s| s == set))
            .collect();
        if chosen.is_empty() {
            return Err(format!("no case belongs to the set `{set}`"));
        }
        Ok(chosen)
    }

    /// What a run depends on, as text: its name, dataset and arguments,
    /// and its scene's arguments (not its group or sets, which only place
    /// it in the tables). A finished run whose definition changed is run
    /// again.
    pub fn definition(&self, case: &Case) -> String {
        let kind = match case.tool {
            CaseTool::Run => "case",
            CaseTool::Loops => "place",
        };
        let mut text = format!("{kind} {} {}", case.name, case.dataset);
        for arg in &case.run_args {
            text.push(' ');
            text.push_str(arg);
        }
        if let Some(scene) = case.scene.as_ref().and_then(|s| self.scenes.get(s)) {
            text.push_str(&format!(
                "\nscene {} {}",
                scene.name,
                scene.synth_args.join(" ")
            ));
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIST: &str = "\
# a comment
scene loop --scene loop --frames 40   # trailing comment
case kitti_orb kitti06-stereo quick,standard $DATA/kitti --extractor orb
case loop_sp loop-stereo standard synth:@loop --levels 1
case loop_rgbd loop-rgbd standard tum:@loop/sequences/00
place loop_place standard synth:@loop/sequences/00 --truth-depth 10
";

    fn parse(text: &str) -> Result<CaseList, CaseListError> {
        CaseList::parse(text, Path::new("cases.txt"))
    }

    #[test]
    fn a_case_list_parses_into_scenes_and_cases() {
        let list = parse(LIST).expect("parses");
        assert_eq!(
            list.scenes["loop"].synth_args,
            ["--scene", "loop", "--frames", "40"]
        );
        assert_eq!(list.cases.len(), 4);
        let place = &list.cases[3];
        assert_eq!(
            (place.tool, place.group.as_str(), place.scene.as_deref()),
            (CaseTool::Loops, "place", Some("loop"))
        );
        assert_eq!(place.run_args, ["--truth-depth", "10"]);
        assert!(list.definition(place).starts_with("place loop_place "));
        let c = &list.cases[0];
        assert_eq!(
            (c.group.as_str(), c.sets.clone()),
            (
                "kitti06-stereo",
                vec!["quick".to_string(), "standard".into()]
            )
        );
        assert_eq!(c.run_args, ["--extractor", "orb"]);
        assert_eq!(list.cases[2].scene.as_deref(), Some("loop"));
        let subs = Substitutions {
            data: "/d".into(),
            suite: "/s".into(),
            scenes: "/o/scenes".into(),
        };
        assert_eq!(
            list.cases[2].resolved_dataset(&subs),
            "tum:/o/scenes/loop/sequences/00"
        );
        assert_eq!(c.resolved_dataset(&subs), "/d/kitti");
        let with_settings = parse("case k g q $DATA/k --settings $SUITE/x.yaml\n").expect("parses");
        assert_eq!(
            with_settings.cases[0].resolved_args(&subs),
            ["--settings", "/s/x.yaml"]
        );
    }

    #[test]
    fn sets_and_names_select_cases() {
        let list = parse(LIST).expect("parses");
        let names = |v: Vec<&Case>| v.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
        assert_eq!(
            names(list.select("quick", &[]).expect("quick")),
            ["kitti_orb"]
        );
        assert_eq!(list.select("all", &[]).expect("all").len(), 4);
        assert!(list.select("nightly", &[]).is_err());
        assert_eq!(
            names(list.select("quick", &["loop_sp".into()]).expect("named")),
            ["loop_sp"]
        );
        assert!(list.select("quick", &["nope".into()]).is_err());
    }

    #[test]
    fn the_definition_covers_the_scene_so_a_changed_scene_reruns_its_cases() {
        let list = parse(LIST).expect("parses");
        let other = parse(&LIST.replace("--frames 40", "--frames 41")).expect("parses");
        assert_ne!(
            list.definition(&list.cases[1]),
            other.definition(&other.cases[1])
        );
        assert_eq!(
            list.definition(&list.cases[0]),
            other.definition(&other.cases[0])
        );
    }

    #[test]
    fn mistakes_name_their_line() {
        for (text, line, needle) in [
            ("case a g quick\n", 1, "needs NAME GROUP SETS DATASET"),
            ("\ncase a g quick synth:@nope\n", 2, "scene `@nope`"),
            ("scene s --scene loop --out x\n", 1, "--out"),
            ("case a g q d\ncase a g q d\n", 2, "defined twice"),
            ("run a\n", 1, "not `run`"),
            ("place a quick\n", 1, "needs NAME SETS DATASET"),
            ("place a q d --curves x\n", 1, "must not set --curves"),
            ("case a/b g q d\n", 1, "not a valid case name"),
            ("case a g q d --out=x\n", 1, "must not set --out"),
            ("case a g q d --inline-mapping\n", 1, "--mapping-thread"),
            (
                "case a g q d --mapping-slowdown 5\n",
                1,
                "needs --mapping-thread",
            ),
            ("case a.log g q d\n", 1, "the suite's own files"),
        ] {
            let err = parse(text).expect_err(text).to_string();
            assert!(err.starts_with(&format!("cases.txt:{line}:")), "{err}");
            assert!(err.contains(needle), "{err}");
        }
    }
}
