//! `mktree catalog create|show|query`: describe files into a catalog, list
//! it, and query every model a region may meet (format-spec/catalog.md).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use mktree::catalog::{Catalog, CatalogAnswer, CatalogModel, CatalogOptions};
use mktree::query::{QueryOptions, Region};
use mktree::store::device::is_remote_url;
use serde_json::json;

use crate::output;

/// A model argument: `KEY=LOCATION`, or `LOCATION` keyed by its file stem.
fn model_argument(arg: &str) -> Result<(String, String)> {
    if let Some((key, location)) = arg.split_once('=').filter(|(k, _)| !k.contains(['/', '\\', ':'])) {
        return Ok((key.to_string(), location.to_string()));
    }
    let stem = Path::new(arg.rsplit('/').next().unwrap_or(arg)).file_stem().and_then(|s| s.to_str());
    match stem {
        Some(stem) if !stem.is_empty() => Ok((stem.to_string(), arg.to_string())),
        _ => bail!("{arg:?} names no model: give KEY=LOCATION"),
    }
}

/// A path given relative to the working folder, as the catalog in `dir`
/// names it: relative to `dir` when it lies below it, else absolute.
fn as_catalog_names(location: &str, dir: &Path) -> Result<String> {
    if is_remote_url(location) {
        return Ok(location.to_string());
    }
    let path = std::fs::canonicalize(location).with_context(|| format!("model file {location}"))?;
    let relative = path.strip_prefix(dir).map(Path::to_path_buf).unwrap_or_else(|_| path.clone());
    relative.to_str().map(str::to_string).with_context(|| format!("{} is not UTF-8", path.display()))
}

pub fn create(output_path: &Path, models: &[String], as_json: bool) -> Result<()> {
    let parent = output_path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let dir: PathBuf = std::fs::canonicalize(parent)
        .with_context(|| format!("the catalog's folder {}", parent.display()))?;
    let mut entries = Vec::with_capacity(models.len());
    for arg in models {
        let (key, location) = model_argument(arg)?;
        entries.push((key, as_catalog_names(&location, &dir)?));
    }
    let named: Vec<(&str, &str)> = entries.iter().map(|(k, l)| (k.as_str(), l.as_str())).collect();
    let catalog = Catalog::describe(&named, Some(&dir), &CatalogOptions::default())?;
    catalog.write(output_path)?;
    print_models(&catalog, as_json)
}

pub fn show(path: &Path, as_json: bool) -> Result<()> {
    print_models(&Catalog::read(path)?, as_json)
}

fn print_models(catalog: &Catalog, as_json: bool) -> Result<()> {
    if as_json {
        let models: Vec<_> = catalog.models().iter().map(model_json).collect();
        return output::json(&json!({ "models": models }));
    }
    println!("{:<24} {:>10} {:>8}  {:<60} location", "model", "objects", "commit", "root box (mm)");
    for m in catalog.models() {
        let b = m.root_box.map_or_else(|| "-".to_string(), |b| format!("{:.0?}", b.to_array()));
        println!("{:<24} {:>10} {:>8}  {:<60} {}", m.key, m.objects, m.commit, b, m.location);
    }
    Ok(())
}

fn model_json(m: &CatalogModel) -> serde_json::Value {
    json!({
        "model": m.key,
        "location": m.location,
        "root_box": m.root_box.map(|b| b.to_array()),
        "objects": m.objects,
        "commit": m.commit,
    })
}

pub fn query(
    path: &Path,
    region: &Region,
    opts: &QueryOptions,
    concurrency: usize,
    as_json: bool,
) -> Result<()> {
    let options = CatalogOptions { concurrency, ..CatalogOptions::default() };
    let reader = Catalog::read(path)?.reader(options);
    let answer = reader.query(region, opts)?;
    if as_json {
        return output::json(&answer_json(&answer));
    }
    for h in answer.hits() {
        println!("{}\t{}\t{}", h.model, h.key, h.object.0);
    }
    println!(
        "{} objects in {} models ({} skipped by their root box), {} block reads",
        answer.hits().count(),
        answer.models.len(),
        answer.skipped,
        answer.block_reads()
    );
    for m in &answer.models {
        if let Some(t) = &m.transfer {
            println!("{}", output::transfer_line(&format!("model {}", m.key), t));
        }
    }
    Ok(())
}

fn answer_json(answer: &CatalogAnswer) -> serde_json::Value {
    let objects: Vec<_> =
        answer.hits().map(|h| json!({ "model": h.model, "key": h.key, "object": h.object.0 })).collect();
    let models: Vec<_> = answer
        .models
        .iter()
        .map(|m| {
            let r = &m.answer.stats.reads;
            json!({
                "model": m.key,
                "objects": m.answer.objects.len(),
                "block_reads": { "node": r.node, "geometry": r.geometry, "total": r.total() },
                "transfer": m.transfer,
            })
        })
        .collect();
    json!({
        "objects": objects,
        "models": models,
        "skipped": answer.skipped,
        "block_reads": answer.block_reads(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn models_are_keyed_by_name_or_by_file_stem() {
        let pair = |k: &str, l: &str| (k.to_string(), l.to_string());
        assert_eq!(model_argument("hull=a/b.mkt").expect("keyed"), pair("hull", "a/b.mkt"));
        assert_eq!(model_argument("a/b.mkt").expect("stem"), pair("b", "a/b.mkt"));
        assert_eq!(
            model_argument("http://h:1/x/deck.mkt?v=2").expect("a URL"),
            pair("deck", "http://h:1/x/deck.mkt?v=2")
        );
        assert!(model_argument("").is_err());
    }
}
