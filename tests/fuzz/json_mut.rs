//! Structure-aware JSON mutation shared by the `gltf`, `camera_path` and `sweep_grid` targets: pick a
//! value by its JSON pointer and set it to an edge value or another type, delete it, or duplicate an
//! array's elements.
//!
//! Edits have a one-line text form (`set /meshes/5/primitives/0/attributes/POSITION 2147483648`,
//! `remove /accessors/3/bufferView`, `dup /nodes/0/children`) so a corpus file can be an edit script
//! that a person reads and writes (see [`parse_script`]), reproduced from its bytes like a seeded case.

use arbitrary::Unstructured;
use serde_json::Value;

/// The JSON pointers of a document's values, by kind (computed once per base document).
pub struct Paths {
    /// Every value below the root.
    pub all: Vec<String>,
    /// Whole numbers outside `min`/`max` arrays: indices, counts, offsets, lengths, enums.
    pub integers: Vec<String>,
    /// Every other number.
    pub numbers: Vec<String>,
    /// Arrays.
    pub arrays: Vec<String>,
}

fn escape(key: &str) -> String {
    key.replace('~', "~0").replace('/', "~1")
}

fn unescape(token: &str) -> String {
    token.replace("~1", "/").replace("~0", "~")
}

/// Every value's pointer in `doc`, sorted into [`Paths`].
pub fn paths(doc: &Value) -> Paths {
    let mut p = Paths {
        all: Vec::new(),
        integers: Vec::new(),
        numbers: Vec::new(),
        arrays: Vec::new(),
    };
    fn walk(v: &Value, here: String, bounds: bool, p: &mut Paths) {
        let children: Vec<(String, &Value, bool)> = match v {
            Value::Object(m) => m
                .iter()
                .map(|(k, c)| (format!("{here}/{}", escape(k)), c, k == "min" || k == "max"))
                .collect(),
            Value::Array(a) => a
                .iter()
                .enumerate()
                .map(|(i, c)| (format!("{here}/{i}"), c, bounds))
                .collect(),
            _ => Vec::new(),
        };
        for (path, c, b) in children {
            match c {
                Value::Number(n) if n.is_u64() && !b => p.integers.push(path.clone()),
                Value::Number(_) => p.numbers.push(path.clone()),
                Value::Array(_) => p.arrays.push(path.clone()),
                _ => {}
            }
            p.all.push(path.clone());
            walk(c, path, b, p);
        }
    }
    walk(doc, String::new(), false, &mut p);
    p
}

/// One edit of a JSON document.
#[derive(Clone, Debug, PartialEq)]
pub enum JsonEdit {
    /// Replace the value at the pointer (or add the key to its object).
    Set(String, Value),
    /// Delete the value (object key or array element).
    Remove(String),
    /// Append a copy of every element of the array (at most 64 of them).
    Dup(String),
}

impl JsonEdit {
    /// Applies the edit; a pointer that no longer resolves (an earlier edit removed it) does nothing.
    pub fn apply(&self, doc: &mut Value) {
        match self {
            JsonEdit::Set(ptr, value) => {
                if let Some(slot) = doc.pointer_mut(ptr) {
                    *slot = value.clone();
                } else if let Some((parent, key)) = split(ptr)
                    && let Some(Value::Object(m)) = doc.pointer_mut(parent)
                {
                    m.insert(unescape(key), value.clone());
                }
            }
            JsonEdit::Remove(ptr) => {
                let Some((parent, key)) = split(ptr) else {
                    return;
                };
                match doc.pointer_mut(parent) {
                    Some(Value::Object(m)) => {
                        m.remove(&unescape(key));
                    }
                    Some(Value::Array(a)) => {
                        if let Ok(i) = key.parse::<usize>()
                            && i < a.len()
                        {
                            a.remove(i);
                        }
                    }
                    _ => {}
                }
            }
            JsonEdit::Dup(ptr) => {
                if let Some(Value::Array(a)) = doc.pointer_mut(ptr) {
                    let copy: Vec<Value> = a.iter().take(64).cloned().collect();
                    a.extend(copy);
                }
            }
        }
    }

    /// The edit's line in a script.
    pub fn line(&self) -> String {
        match self {
            JsonEdit::Set(p, v) => format!("set {p} {v}"),
            JsonEdit::Remove(p) => format!("remove {p}"),
            JsonEdit::Dup(p) => format!("dup {p}"),
        }
    }

    /// Parses [`JsonEdit::line`]'s form; `None` for another kind of line.
    pub fn parse(line: &str) -> Option<JsonEdit> {
        let (verb, rest) = line.split_once(' ')?;
        match verb {
            "set" => {
                let (ptr, json) = rest.split_once(' ')?;
                Some(JsonEdit::Set(
                    ptr.to_string(),
                    serde_json::from_str(json).ok()?,
                ))
            }
            "remove" => Some(JsonEdit::Remove(rest.trim().to_string())),
            "dup" => Some(JsonEdit::Dup(rest.trim().to_string())),
            _ => None,
        }
    }
}

/// (parent pointer, last token) of a pointer below the root.
fn split(ptr: &str) -> Option<(&str, &str)> {
    ptr.rsplit_once('/')
}

/// Numbers at the edges of every integer and float type a reader might use, and strings where numbers
/// belong.
pub const EDGES: &[&str] = &[
    "-1",
    "0",
    "1",
    "2",
    "3",
    "255",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "9007199254740993",
    "18446744073709551615",
    "1e20",
    "1e308",
    "-1e308",
    "0.5",
    "-0.0",
    "1e-300",
    "\"NaN\"",
    "\"inf\"",
];

/// An edge value, or the value at `ptr` in `doc` moved a little (±1, ×2, ×1000).
pub fn edge_value(u: &mut Unstructured, doc: &Value, ptr: &str) -> arbitrary::Result<Value> {
    let current = doc.pointer(ptr).and_then(Value::as_f64);
    if let Some(x) = current
        && u.ratio(1, 4)?
    {
        let y = match u.int_in_range(0..=3)? {
            0 => x + 1.0,
            1 => x - 1.0,
            2 => x * 2.0,
            _ => x * 1000.0,
        };
        if y.fract() == 0.0 && (0.0..1e15).contains(&y) {
            return Ok(Value::from(y as u64));
        }
        if y.fract() == 0.0 && (-1e15..0.0).contains(&y) {
            return Ok(Value::from(y as i64));
        }
        return Ok(serde_json::Number::from_f64(y).map_or(Value::Null, Value::Number));
    }
    let text = u.choose(EDGES)?;
    Ok(serde_json::from_str(text).unwrap_or(Value::Null))
}

/// A value of some other JSON type.
pub fn odd_value(u: &mut Unstructured) -> arbitrary::Result<Value> {
    let text = u.choose(&[
        "null",
        "true",
        "\"x\"",
        "\"\"",
        "[]",
        "{}",
        "[0]",
        "[-1, 2147483648]",
        "{\"a\": 1}",
        "[[[[[[[[[[[[[[[[0]]]]]]]]]]]]]]]]",
    ])?;
    Ok(serde_json::from_str(text).unwrap_or(Value::Null))
}

/// One random structural edit of a document whose pointers are `paths`: mostly numbers set to edge
/// values (integers preferred: they are the indices, counts and offsets), some deletions, type swaps
/// and duplicated arrays.
pub fn random_edit(
    u: &mut Unstructured,
    doc: &Value,
    paths: &Paths,
) -> arbitrary::Result<JsonEdit> {
    let pick =
        |u: &mut Unstructured, list: &[String], fallback: &[String]| -> arbitrary::Result<String> {
            let list = if list.is_empty() { fallback } else { list };
            Ok(u.choose(list)?.clone())
        };
    // A document without integers (a camera path) gets its numbers edited instead.
    let integers = if paths.integers.is_empty() {
        &paths.numbers
    } else {
        &paths.integers
    };
    Ok(match u.int_in_range(0..=99)? {
        0..=49 => {
            let p = pick(u, integers, &paths.all)?;
            let v = edge_value(u, doc, &p)?;
            JsonEdit::Set(p, v)
        }
        50..=61 => {
            let p = pick(u, &paths.numbers, &paths.all)?;
            let v = edge_value(u, doc, &p)?;
            JsonEdit::Set(p, v)
        }
        62..=75 => JsonEdit::Remove(pick(u, &paths.all, &paths.all)?),
        76..=85 => JsonEdit::Set(pick(u, &paths.all, &paths.all)?, odd_value(u)?),
        _ => JsonEdit::Dup(pick(u, &paths.arrays, &paths.all)?),
    })
}

/// The lines of an edit script after its first (magic) line: blank lines and `#` comments skipped.
pub fn script_lines(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .skip(1)
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
}

/// An edit script: a corpus file whose first line is the target's magic line.
#[derive(Default)]
pub struct Script {
    /// Its JSON edits, in order.
    pub json: Vec<JsonEdit>,
    /// Its other lines (target-specific edits), in order.
    pub other: Vec<String>,
    /// The text the refusal must contain (`expect-error TEXT`), if any.
    pub expect: Option<String>,
}

/// The script in `bytes` if they start with `magic`; `None`: seeded bytes.
pub fn parse_script(bytes: &[u8], magic: &str) -> Option<Script> {
    let text = std::str::from_utf8(bytes).ok()?;
    if !text.starts_with(magic) {
        return None;
    }
    let mut script = Script::default();
    for line in script_lines(text) {
        if let Some(e) = line.strip_prefix("expect-error ") {
            script.expect = Some(e.to_string());
        } else if let Some(e) = JsonEdit::parse(line) {
            script.json.push(e);
        } else {
            script.other.push(line.to_string());
        }
    }
    Some(script)
}

/// Checks a script's `expect-error`: a refusal whose message lacks the text, or an acceptance, becomes
/// a failure.
pub fn expect_refusal(
    verdict: crate::harness::Verdict,
    expect: Option<&str>,
) -> crate::harness::Verdict {
    use crate::harness::Verdict;
    match (expect, verdict) {
        (None, v) => v,
        (Some(want), Verdict::Refused(msg)) if msg.contains(want) => Verdict::Refused(msg),
        (Some(want), Verdict::Refused(msg)) => {
            Verdict::AcceptedCorruption(format!("refused with «{msg}», expected «{want}»"))
        }
        (Some(want), Verdict::Accepted) => {
            Verdict::AcceptedCorruption(format!("accepted, expected a refusal with «{want}»"))
        }
        (Some(_), v) => v,
    }
}
