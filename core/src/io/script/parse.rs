//! Parsing a script: TOML to [`Script`], with errors that name the file, line, column and
//! field (the spans of each step's keys), and reading a script file through the size cap.

use super::*;

/// Why a script could not be read or run: where (file, line, column, step) and what.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{file}{}: {message}", Location { line: *line, column: *column, step: *step })]
pub struct ScriptError {
    pub file: String,
    /// 1-based line and column, when known.
    pub line: Option<usize>,
    pub column: Option<usize>,
    /// 1-based index of the failing step, when known.
    pub step: Option<usize>,
    pub message: String,
}

/// The `:line:column: step N` between a script error's file and message (each part only
/// when known; the column only with a line).
pub(super) struct Location {
    line: Option<usize>,
    column: Option<usize>,
    step: Option<usize>,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
            if let Some(c) = self.column {
                write!(f, ":{c}")?;
            }
        }
        if let Some(s) = self.step {
            write!(f, ": step {s}")?;
        }
        Ok(())
    }
}

/// 1-based line and column of a byte offset.
pub(super) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |n| n + 1) + 1;
    (line, column)
}

/// Parses and checks a script; `file` names it in errors.
///
/// # Errors
/// TOML syntax or type errors with their line, column and the offending field (from the
/// parser's message; for a field inside a step the position is the step's `[[step]]` header,
/// because tagged steps are read as a whole); then semantic errors (wrong version, bad tool parameters, empty paths)
/// naming the step and its line.
pub fn parse_script(text: &str, file: &str) -> Result<Script, ScriptError> {
    let spans = Spans::new(text);
    let mut script: Script = toml::from_str(text).map_err(|e| {
        let message = e.message().trim().to_string();
        let (line, column) = match e.span() {
            Some(span) => {
                let (l, c) = line_col(text, span.start);
                // Inside a step the parser points at the step's table (tagged steps are read
                // as a whole); point at the named field's own line when the step has it.
                let field_line = backticked(&message).and_then(|key| {
                    let n = spans.step_at(span.start)?;
                    spans.step_key_line(n, key)
                });
                match field_line {
                    Some(field_line) => (Some(field_line), None),
                    None => (Some(l), Some(c)),
                }
            }
            None => (None, None),
        };
        ScriptError {
            file: file.to_string(),
            line,
            column,
            step: None,
            message,
        }
    })?;
    let at = |n: usize, fault: StepFault| ScriptError {
        file: file.to_string(),
        line: spans
            .step_key_line(n, fault.key)
            .or_else(|| spans.step_line(n)),
        column: None,
        step: Some(n + 1),
        message: fault.message,
    };
    let top = |path: &[&str], message: String| ScriptError {
        file: file.to_string(),
        line: spans.key_line(path),
        column: None,
        step: None,
        message,
    };
    if script.version != SCRIPT_VERSION {
        return Err(top(
            &["version"],
            format!(
                "version = {} is not supported (this build reads version {SCRIPT_VERSION})",
                script.version
            ),
        ));
    }
    if let Some(s) = script.seconds
        && !(s.is_finite() && s > 0.0 && s <= 3600.0)
    {
        return Err(top(
            &["seconds"],
            format!("seconds = {s} must be in (0, 3600]"),
        ));
    }
    if let Some(c) = &script.clay
        && !(8..=96).contains(&c.resolution)
    {
        return Err(top(
            &["clay", "resolution"],
            format!(
                "clay.resolution = {} must be between 8 and 96",
                c.resolution
            ),
        ));
    }
    if let Some(a) = script.autosave
        && !(a.every_s.is_finite() && a.every_s >= 0.0)
    {
        return Err(top(
            &["autosave", "every_s"],
            format!("autosave.every_s = {} must be finite and ≥ 0", a.every_s),
        ));
    }
    if script.steps.len() > MAX_STEPS {
        return Err(top(
            &["step"],
            format!(
                "the script has {} steps; at most {MAX_STEPS} are allowed",
                script.steps.len()
            ),
        ));
    }
    for (n, step) in script.steps.iter().enumerate() {
        check_step(step).map_err(|f| at(n, f))?;
    }
    script.deprecated = spans
        .renamed_keys()
        .into_iter()
        .map(|(line, key, replacement)| DeprecatedKey {
            file: file.to_string(),
            line,
            key,
            replacement,
        })
        .collect();
    script.step_lines = (0..script.steps.len())
        .map(|n| spans.step_line(n).unwrap_or(0))
        .collect();
    Ok(script)
}

/// Where keys and steps are written in a script's text, from the TOML parser's spans (no
/// searching of the text or of messages). Built from text that may not parse; then nothing
/// is found and errors fall back to the parser's own position.
pub(super) struct Spans<'t> {
    text: &'t str,
    document: Option<toml::Spanned<toml::de::DeTable<'t>>>,
}

impl<'t> Spans<'t> {
    fn new(text: &'t str) -> Self {
        Self {
            text,
            document: toml::de::DeTable::parse(text).ok(),
        }
    }

    fn line(&self, offset: usize) -> usize {
        line_col(self.text, offset).0
    }

    /// The `[[step]]` tables, in order.
    fn steps(&self) -> &[toml::Spanned<toml::de::DeValue<'t>>] {
        match self.document.as_ref().and_then(|d| d.get_ref().get("step")) {
            Some(v) => match v.get_ref() {
                toml::de::DeValue::Array(a) => a,
                _ => &[],
            },
            None => &[],
        }
    }

    /// Line of the key at `path` (a top-level key, or a key of a table).
    fn key_line(&self, path: &[&str]) -> Option<usize> {
        let mut table = self.document.as_ref()?.get_ref();
        let (last, parents) = path.split_last()?;
        for key in parents {
            match table.get(*key)?.get_ref() {
                toml::de::DeValue::Table(t) => table = t,
                toml::de::DeValue::Array(a) => match a.first()?.get_ref() {
                    toml::de::DeValue::Table(t) => table = t,
                    _ => return None,
                },
                _ => return None,
            }
        }
        let (key, _) = table.iter().find(|(k, _)| k.get_ref() == last)?;
        Some(self.line(key.span().start))
    }

    /// Every key written under an old name of [`RENAMED_KEYS`], as (line, old name, new
    /// name), in file order.
    fn renamed_keys(&self) -> Vec<(usize, &'static str, &'static str)> {
        let mut found = Vec::new();
        if let Some(document) = &self.document {
            self.collect_renamed(document.get_ref(), &mut found);
        }
        // In file order (a table's keys may come back in another order).
        found.sort_by_key(|&(offset, ..)| offset);
        found
            .into_iter()
            .map(|(offset, old, new)| (self.line(offset), old, new))
            .collect()
    }

    fn collect_renamed(
        &self,
        table: &toml::de::DeTable<'t>,
        found: &mut Vec<(usize, &'static str, &'static str)>,
    ) {
        // Byte offsets here; `renamed_keys` turns them into lines.
        for (k, v) in table.iter() {
            if let Some(&(old, new)) = RENAMED_KEYS.iter().find(|(old, _)| k.get_ref() == *old) {
                found.push((k.span().start, old, new));
            }
            self.collect_renamed_in(v.get_ref(), found);
        }
    }

    fn collect_renamed_in(
        &self,
        value: &toml::de::DeValue<'t>,
        found: &mut Vec<(usize, &'static str, &'static str)>,
    ) {
        match value {
            toml::de::DeValue::Table(t) => self.collect_renamed(t, found),
            toml::de::DeValue::Array(a) => {
                for v in a {
                    self.collect_renamed_in(v.get_ref(), found);
                }
            }
            _ => {}
        }
    }

    /// Which step's table holds byte `offset`.
    fn step_at(&self, offset: usize) -> Option<usize> {
        self.steps().iter().position(|s| s.span().contains(&offset))
    }

    /// Line where step `n`'s table starts.
    fn step_line(&self, n: usize) -> Option<usize> {
        Some(self.line(self.steps().get(n)?.span().start))
    }

    /// Line of `key` in step `n`, looked up in the step's table and then in the inline tables
    /// it holds (`shape = { radius_fu = … }`).
    fn step_key_line(&self, n: usize, key: &str) -> Option<usize> {
        let toml::de::DeValue::Table(table) = self.steps().get(n)?.get_ref() else {
            return None;
        };
        // A renamed key may be written under its old name.
        let old = RENAMED_KEYS
            .iter()
            .find(|(_, new)| *new == key)
            .map(|(old, _)| *old);
        let is_key = |k: &str| k == key || Some(k) == old;
        let direct = table.iter().find(|(k, _)| is_key(k.get_ref()));
        let nested = || {
            table.iter().find_map(|(_, v)| match v.get_ref() {
                toml::de::DeValue::Table(inner) => inner.iter().find(|(k, _)| is_key(k.get_ref())),
                _ => None,
            })
        };
        let (k, _) = direct.or_else(nested)?;
        Some(self.line(k.span().start))
    }
}

/// Reads and parses the script at `path` (named by its path in errors).
///
/// # Errors
/// When the file cannot be read (no line), or as [`parse_script`].
pub fn load_script(path: &std::path::Path) -> Result<Script, ScriptError> {
    let file = path.display().to_string();
    let fail = |message: String| ScriptError {
        file: file.clone(),
        line: None,
        column: None,
        step: None,
        message,
    };
    let bytes = crate::io::bounded_read::read_regular_file(path, MAX_SCRIPT_BYTES)
        .map_err(|e| fail(format!("cannot read the script: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        fail(format!(
            "the script is not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ))
    })?;
    parse_script(&text, &file)
}

/// The first `` `name` `` in a parser message.
pub(super) fn backticked(message: &str) -> Option<&str> {
    let start = message.find('`')? + 1;
    let len = message[start..].find('`')?;
    Some(&message[start..start + len]).filter(|k| !k.is_empty())
}
