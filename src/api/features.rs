//! Tree listings: GeoJSON (`/v1/trees`) and OGC API Features items
//! (`/v1/collections/trees/items`).
//!
//! Pages are ordered by tree id (UUIDv7, so by creation time) and the cursor
//! is the last id of a page: stable under concurrent inserts, and a plain
//! index range scan for the database. Coordinates are in the trees' own CRS;
//! the service does not reproject.

use std::sync::Arc;

use axum::Router;
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde::Deserialize;
use utoipa::IntoParams;
use uuid::Uuid;

use super::error::Problem;
use super::extract::ApiQuery;
use super::schema::{Link, TreeCollection, TreeFeature, rfc3339};
use super::{ApiError, AppState, BaseUrl, ReadAccess};
use crate::store::{TreeFilter, now_ms};

/// GeoJSON media type.
const GEO_JSON: &str = "application/geo+json";
/// Largest page.
const MAX_LIMIT: u32 = 10_000;

pub(super) fn routes() -> Router<Arc<AppState>> {
    Router::new().route("/v1/collections/trees/items", get(collection_items))
}

/// Filters and paging of a tree listing.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct ListQuery {
    /// `min_x,min_y,max_x,max_y` in the trees' CRS.
    #[param(value_type = Option<super::schema::BboxText>, inline)]
    bbox: Option<String>,
    /// Exact species name.
    #[param(pattern = r"^[^\u0000]*$")]
    species: Option<String>,
    /// Smallest height in metres.
    min_height: Option<f64>,
    /// Largest height in metres.
    max_height: Option<f64>,
    /// Exact CRS, e.g. `EPSG:28992`.
    #[param(pattern = r"^[^\u0000]*$")]
    crs: Option<String>,
    /// Page size, 1 to 10000 (default 100).
    #[param(minimum = 1, maximum = 10000)]
    limit: Option<u32>,
    /// The `next` link's cursor: continue after this tree id.
    cursor: Option<Uuid>,
}

impl ListQuery {
    fn filter(&self) -> Result<TreeFilter, ApiError> {
        let limit = self.limit.unwrap_or(100);
        if !(1..=MAX_LIMIT).contains(&limit) {
            return Err(ApiError::BadRequest(format!(
                "limit: expected 1 to {MAX_LIMIT}, found {limit}"
            )));
        }
        for (name, value) in [
            ("min_height", self.min_height),
            ("max_height", self.max_height),
        ] {
            // NaN would bind as NULL on SQLite (no filter) and match nothing
            // on PostgreSQL: refuse it, as `parse_bbox` refuses it.
            if let Some(h) = value.filter(|h| !h.is_finite()) {
                return Err(ApiError::BadRequest(format!(
                    "{name}: expected a finite number of metres, found {h}"
                )));
            }
        }
        if let (Some(lo), Some(hi)) = (self.min_height, self.max_height) {
            if lo > hi {
                return Err(ApiError::BadRequest(format!(
                    "min_height {lo} exceeds max_height {hi}"
                )));
            }
        }
        Ok(TreeFilter {
            bbox: self.bbox.as_deref().map(parse_bbox).transpose()?,
            species: self.species.clone(),
            min_height_m: self.min_height,
            max_height_m: self.max_height,
            crs: self.crs.clone(),
            after: self.cursor,
            limit,
        })
    }

    /// The query string of the next page.
    fn next_query(&self, after: Uuid, limit: u32) -> String {
        let mut parts = vec![format!("limit={limit}"), format!("cursor={after}")];
        if let Some(bbox) = &self.bbox {
            parts.push(format!("bbox={}", encode(bbox)));
        }
        if let Some(species) = &self.species {
            parts.push(format!("species={}", encode(species)));
        }
        if let Some(h) = self.min_height {
            parts.push(format!("min_height={h}"));
        }
        if let Some(h) = self.max_height {
            parts.push(format!("max_height={h}"));
        }
        if let Some(crs) = &self.crs {
            parts.push(format!("crs={}", encode(crs)));
        }
        parts.join("&")
    }
}

/// Parses `min_x,min_y,max_x,max_y`.
pub(super) fn parse_bbox(text: &str) -> Result<[f64; 4], ApiError> {
    let bad = || {
        ApiError::BadRequest(format!(
            "bbox: expected min_x,min_y,max_x,max_y (finite, min <= max), found {text:?}"
        ))
    };
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let [min_x, min_y, max_x, max_y] = <[f64; 4]>::try_from(values).map_err(|_| bad())?;
    let ok = [min_x, min_y, max_x, max_y].iter().all(|v| v.is_finite())
        && min_x <= max_x
        && min_y <= max_y;
    if ok {
        Ok([min_x, min_y, max_x, max_y])
    } else {
        Err(bad())
    }
}

/// Percent-encodes a query value (RFC 3986 unreserved characters kept).
fn encode(value: &str) -> String {
    value
        .bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' | b',' => {
                char::from(b).to_string()
            }
            other => format!("%{other:02X}"),
        })
        .collect()
}

/// One page of trees as a FeatureCollection with `self` and `next` links.
async fn page(
    state: &AppState,
    base: &str,
    path: &str,
    query: &ListQuery,
) -> Result<Response, ApiError> {
    let filter = query.filter()?;
    let rows = state.store.trees(&filter).await?;
    let mut links = vec![Link::new(format!("{base}{path}"), "self", GEO_JSON)];
    if rows.len() == filter.limit as usize {
        if let Some(last) = rows.last() {
            let next = query.next_query(last.id, filter.limit);
            links.push(Link::new(format!("{base}{path}?{next}"), "next", GEO_JSON));
        }
    }
    let collection = TreeCollection {
        collection_type: "FeatureCollection".into(),
        number_returned: rows.len(),
        features: rows
            .iter()
            .map(|r| TreeFeature::from_row(r, base))
            .collect(),
        time_stamp: rfc3339(now_ms()),
        links,
    };
    let body = serde_json::to_vec(&collection).map_err(|e| ApiError::Internal(e.to_string()))?;
    Ok(([(header::CONTENT_TYPE, GEO_JSON)], body).into_response())
}

/// Trees as GeoJSON points at their trunk bases, filtered and paged.
///
/// A bbox or height filter matches only reconstructed trees (those have a
/// location and a height).
#[utoipa::path(
    get,
    path = "/v1/trees",
    tag = "trees",
    params(ListQuery),
    responses(
        (status = 200, description = "A page of trees", body = TreeCollection, content_type = "application/geo+json"),
        (status = 400, description = "Bad filter", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn list_trees(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    BaseUrl(base): BaseUrl,
    ApiQuery(query): ApiQuery<ListQuery>,
) -> Result<Response, ApiError> {
    page(&state, &base, "/v1/trees", &query).await
}

/// The trees collection's items, in OGC API Features (Part 1) form: `limit`,
/// `bbox` and `next` links; also `species`, `min_height` and `max_height`.
#[utoipa::path(
    get,
    path = "/v1/collections/trees/items",
    tag = "trees",
    params(ListQuery),
    responses(
        (status = 200, description = "A page of trees", body = TreeCollection, content_type = "application/geo+json"),
        (status = 400, description = "Bad filter", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn collection_items(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    BaseUrl(base): BaseUrl,
    ApiQuery(query): ApiQuery<ListQuery>,
) -> Result<Response, ApiError> {
    page(&state, &base, "/v1/collections/trees/items", &query).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bbox_is_four_ordered_finite_numbers() {
        assert_eq!(parse_bbox("1,2,3,4").unwrap(), [1.0, 2.0, 3.0, 4.0]);
        assert_eq!(parse_bbox(" 1 , 2,3,4").unwrap(), [1.0, 2.0, 3.0, 4.0]);
        for bad in ["1,2,3", "1,2,3,4,5", "a,2,3,4", "3,2,1,4", "1,2,3,inf", ""] {
            assert!(parse_bbox(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn next_link_keeps_the_filters() {
        let query = ListQuery {
            bbox: Some("1,2,3,4".into()),
            species: Some("Quercus robur".into()),
            min_height: Some(2.5),
            ..ListQuery::default()
        };
        let id = Uuid::nil();
        assert_eq!(
            query.next_query(id, 10),
            format!("limit=10&cursor={id}&bbox=1,2,3,4&species=Quercus%20robur&min_height=2.5")
        );
    }
}
