//! A query over a catalog (format-spec/catalog.md, "What a reader does"):
//! the models whose root box the region may meet are opened, once, checked
//! against their entries, and queried in parallel; the others get no
//! request.

use std::sync::OnceLock;

use super::open::{CatalogOptions, in_parallel, open};
use super::{Catalog, CatalogError, CatalogModel};
use crate::db::Database;
use crate::query::{QueryAnswer, QueryOptions, Region, Selection, query_region};
use crate::scene::{Key, ObjectId};
use crate::store::TransferCounts;

/// Opens a catalog's models on demand and answers queries across them.
pub struct CatalogReader {
    catalog: Catalog,
    options: CatalogOptions,
    opened: Vec<OnceLock<Database>>,
}

/// One model's part of a catalog answer.
#[derive(Debug, Clone)]
pub struct ModelAnswer {
    /// The model's index in the catalog.
    pub model: usize,
    /// The model's key.
    pub key: String,
    /// The model's own answer: objects, keys, block reads.
    pub answer: QueryAnswer,
    /// What its file's device fetched for this query (its open too, if the
    /// query opened it); `None` for a local file. Exact when no other query
    /// runs on the reader at the same time.
    pub transfer: Option<TransferCounts>,
}

/// An object a catalog query found, named by its model and its own key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CatalogHit<'a> {
    /// The model's key.
    pub model: &'a str,
    /// The object's id in its model's file.
    pub object: ObjectId,
    /// The object's key in its model.
    pub key: &'a Key,
}

/// A catalog query's answer: the answers of the models whose root box the
/// region may meet, in catalog order.
#[derive(Debug, Clone)]
pub struct CatalogAnswer {
    /// The models queried.
    pub models: Vec<ModelAnswer>,
    /// Models left out by their root box (no request, not opened).
    pub skipped: usize,
}

impl CatalogAnswer {
    /// Every object found, model by model, each model's in id order.
    pub fn hits(&self) -> impl Iterator<Item = CatalogHit<'_>> {
        self.models.iter().flat_map(|m| {
            m.answer.objects.iter().zip(&m.answer.keys).map(|(&object, key)| CatalogHit {
                model: m.key.as_str(),
                object,
                key,
            })
        })
    }

    /// Block reads over every model queried.
    pub fn block_reads(&self) -> u64 {
        self.models.iter().map(|m| m.answer.stats.reads.total()).sum()
    }
}

impl CatalogReader {
    pub(super) fn new(catalog: Catalog, options: CatalogOptions) -> CatalogReader {
        let opened = catalog.models().iter().map(|_| OnceLock::new()).collect();
        CatalogReader { catalog, options, opened }
    }

    /// The catalog read.
    pub fn catalog(&self) -> &Catalog {
        &self.catalog
    }

    /// The indexes of the models whose root box `region` may meet.
    pub fn models_met(&self, region: &Region) -> Vec<usize> {
        let meets = |m: &CatalogModel| m.root_box.as_ref().is_some_and(|b| region.may_meet_box(b));
        self.catalog.models().iter().enumerate().filter(|(_, m)| meets(m)).map(|(i, _)| i).collect()
    }

    /// How many models have been opened so far.
    pub fn opened(&self) -> usize {
        self.opened.iter().filter(|d| d.get().is_some()).count()
    }

    /// Model `i`'s database, opened and checked against its entry on first
    /// use; whether this call opened it.
    pub fn database(&self, i: usize) -> Result<(&Database, bool), CatalogError> {
        let model = self
            .catalog
            .models()
            .get(i)
            .ok_or(CatalogError::NoModel { index: i, models: self.opened.len() })?;
        if let Some(db) = self.opened[i].get() {
            return Ok((db, false));
        }
        let db = open(&model.key, &model.location, self.catalog.base(), &self.options)?;
        let found = CatalogModel::of(&model.key, &model.location, &db)?;
        if found.commit != model.commit {
            return Err(CatalogError::Stale {
                model: model.key.clone(),
                catalog: model.commit,
                file: found.commit,
            });
        }
        if found != *model {
            return Err(CatalogError::Mismatch {
                model: model.key.clone(),
                commit: found.commit,
                detail: format!(
                    "the file holds {} objects in {:?}, the catalog says {} in {:?}",
                    found.objects, found.root_box, model.objects, model.root_box
                ),
            });
        }
        // Two queries may open a model at once: one database is kept.
        let kept = self.opened[i].get_or_init(|| db);
        Ok((kept, true))
    }

    /// The objects meeting `region` at `opts`' level, in every model whose
    /// root box it may meet, queried in parallel.
    pub fn query(&self, region: &Region, opts: &QueryOptions) -> Result<CatalogAnswer, CatalogError> {
        region.check_input().map_err(|e| CatalogError::Region(Box::new(e)))?;
        let met = self.models_met(region);
        let answers =
            in_parallel(met.len(), self.options.concurrency, |j| self.query_model(met[j], region, opts));
        Ok(CatalogAnswer {
            models: answers.into_iter().collect::<Result<_, _>>()?,
            skipped: self.catalog.models().len() - met.len(),
        })
    }

    fn query_model(
        &self,
        i: usize,
        region: &Region,
        opts: &QueryOptions,
    ) -> Result<ModelAnswer, CatalogError> {
        let (db, opened_now) = self.database(i)?;
        let before = if opened_now { Some(TransferCounts::default()) } else { db.transfer_counts() };
        let key = self.catalog.models()[i].key.clone();
        let failed = |source| CatalogError::Query { model: key.clone(), source: Box::new(source) };
        let snapshot = db.begin_read().map_err(|e| failed(e.into()))?;
        // A local file is read at its latest commit, which may have moved on.
        let commit = self.catalog.models()[i].commit;
        if snapshot.txn() != commit {
            return Err(CatalogError::Stale { model: key, catalog: commit, file: snapshot.txn() });
        }
        let answer = query_region(&snapshot, region, opts, None).map_err(failed)?;
        let transfer = db.transfer_counts().zip(before).map(|(after, before)| after.since(&before));
        Ok(ModelAnswer { model: i, key, answer, transfer })
    }
}
