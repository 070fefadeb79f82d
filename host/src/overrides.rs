//! `--set KEY=VALUE`: overrides of any value of a scene file, applied to its TOML before
//! it is parsed, so that an overridden value is checked like one written in the file.
//!
//! `KEY` is the dotted field path the scene errors use (`render.light_rays`,
//! `camera.eye`, `light[0].intensity`, `material[2].diffuse`); `VALUE` is a TOML value
//! (`128`, `[0, 1, 3]`, `"auto"`), or a bare word taken as a string (`auto`). A key the
//! file does not have is added (a missing table too). The file's other lines are kept
//! as they are.
//!
//! ```text
//! magg-host render scenes/cornell.toml --out c.png --set render.light_rays=128 --set camera.eye=[0,1,4]
//! ```

use anyhow::{bail, Context};
use std::str::FromStr;
use toml_edit::{DocumentMut, Item, Table, Value};

/// The `--set` flags of a command that reads a scene.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SetArgs {
    /// Override a value of the scene file, KEY=VALUE: KEY a field as scene errors name it
    /// (render.light_rays, camera.eye, light[0].intensity), VALUE a TOML value (128,
    /// [0,1,4], "auto"). Repeatable; applied in order before the scene is checked.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

impl SetArgs {
    /// The overrides, each checked.
    pub fn overrides(&self) -> anyhow::Result<Vec<Override>> {
        self.set.iter().map(|s| s.parse()).collect()
    }
}

/// One `--set KEY=VALUE`.
#[derive(Clone, Debug)]
pub struct Override {
    /// The path, one step per dotted part: a key, with an index for `name[i]`.
    path: Vec<(String, Option<usize>)>,
    /// The value.
    value: Value,
    /// As the user wrote it, for messages.
    text: String,
}

impl FromStr for Override {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> anyhow::Result<Override> {
        let (key, value) = s.split_once('=').with_context(|| format!("--set {s}: expected KEY=VALUE"))?;
        let path = key
            .trim()
            .split('.')
            .map(|part| {
                let (name, index) = match part.split_once('[') {
                    Some((name, rest)) => {
                        let i = rest.strip_suffix(']').and_then(|i| i.parse::<usize>().ok());
                        let Some(i) = i else { bail!("--set {s}: {part:?} is not NAME or NAME[INDEX]") };
                        (name, Some(i))
                    }
                    None => (part, None),
                };
                if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                    bail!("--set {s}: {part:?} is not a field name");
                }
                Ok((name.to_string(), index))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let value = value.trim();
        let value = match format!("v = {value}").parse::<DocumentMut>() {
            Ok(doc) => match doc.get("v").and_then(Item::as_value) {
                Some(v) => v.clone().decorated("", ""),
                None => bail!("--set {s}: {value:?} is a table, not a value"),
            },
            // A bare word: a string (`--set render.exposure=auto`).
            Err(_) if !value.is_empty() && value.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') => {
                Value::from(value)
            }
            Err(e) => bail!("--set {s}: {value:?} is not a TOML value: {}", e.message()),
        };
        Ok(Override { path, value, text: s.to_string() })
    }
}

impl std::fmt::Display for Override {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "--set {}", self.text)
    }
}

/// The scene text `text` with every override applied, in order.
pub fn apply(text: &str, overrides: &[Override]) -> anyhow::Result<String> {
    let mut doc: DocumentMut = text.parse().context("the scene is not valid TOML")?;
    for o in overrides {
        set(doc.as_table_mut(), o).with_context(|| o.to_string())?;
    }
    Ok(doc.to_string())
}

fn set(root: &mut Table, o: &Override) -> anyhow::Result<()> {
    let (last, steps) = o.path.split_last().context("an empty key")?;
    let mut table = root;
    for (name, index) in steps {
        table = step(table, name, *index)?;
    }
    let (name, index) = last;
    match index {
        None => {
            table.insert(name, Item::Value(o.value.clone()));
        }
        Some(i) => {
            let array = table.get_mut(name).and_then(Item::as_array_mut);
            let slot = array.and_then(|a| a.get_mut(*i)).with_context(|| format!("{name}[{i}] is not in the scene"))?;
            *slot = o.value.clone();
        }
    }
    Ok(())
}

/// The table at `name` (or `name[index]`) inside `table`; a missing plain table is added.
fn step<'t>(table: &'t mut Table, name: &str, index: Option<usize>) -> anyhow::Result<&'t mut Table> {
    match index {
        Some(i) => table
            .get_mut(name)
            .and_then(Item::as_array_of_tables_mut)
            .and_then(|a| a.get_mut(i))
            .with_context(|| format!("{name}[{i}] is not in the scene")),
        None => {
            let item = table.entry(name).or_insert(Item::Table(Table::new()));
            item.as_table_mut().with_context(|| format!("{name} is not a table"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = "[camera]\neye = [0, 1, 3] # the eye\nlook_at = [0, 1, 0]\n\n[[light]]\nposition = [0, 2, 0]\n\n[[light]]\nposition = [1, 2, 0]\n";

    fn over(s: &str) -> Override {
        s.parse().unwrap()
    }

    #[test]
    fn values_are_replaced_in_place_and_the_rest_of_the_file_kept() {
        let out = apply(SCENE, &[over("camera.eye=[0,1,4]"), over("light[1].position = [5, 5, 5]")]).unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(doc["camera"]["eye"].as_array().unwrap()[2].as_integer(), Some(4));
        assert_eq!(doc["light"].as_array().unwrap()[1]["position"].as_array().unwrap()[0].as_integer(), Some(5));
        assert_eq!(doc["light"].as_array().unwrap()[0]["position"].as_array().unwrap()[0].as_integer(), Some(0));
        assert!(out.contains("look_at = [0, 1, 0]\n"), "{out}");
        assert_eq!(out.lines().count(), SCENE.lines().count(), "a replaced value moves no line");
    }

    #[test]
    fn missing_keys_and_tables_are_added_and_bare_words_are_strings() {
        let out = apply(SCENE, &[over("render.light_rays=128"), over("render.exposure=auto")]).unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(doc["render"]["light_rays"].as_integer(), Some(128));
        assert_eq!(doc["render"]["exposure"].as_str(), Some("auto"));
    }

    #[test]
    fn bad_overrides_say_why() {
        for (s, why) in [
            ("render.width", "expected KEY=VALUE"),
            ("render.wid th=3", "not a field name"),
            ("light[x].position=[0,0,0]", "NAME[INDEX]"),
            ("render.width=[1,", "not a TOML value"),
        ] {
            let e = s.parse::<Override>().unwrap_err().to_string();
            assert!(e.contains(why), "{s}: {e}");
        }
        let e = apply(SCENE, &[over("light[5].position=[0,0,0]")]).unwrap_err();
        assert!(format!("{e:#}").contains("light[5] is not in the scene"), "{e:#}");
        let e = apply(SCENE, &[over("camera.eye.x=1")]).unwrap_err();
        assert!(format!("{e:#}").contains("eye is not a table"), "{e:#}");
    }
}
