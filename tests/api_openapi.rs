//! The committed OpenAPI document matches the code, and the server what it says.
//!
//! Regenerate it with `UPDATE_OPENAPI=1 cargo test --test api_openapi` or
//! `silva serve --print-openapi > openapi/openapi.json`. The server's
//! answers are checked against the bounds the document states.

mod common;

use common::{TestDb, TestServer, assert_problem, config};
use serde_json::Value;

#[test]
fn committed_spec_is_current() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.json");
    let generated = silva::api::openapi_json();
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        // Regenerating checks nothing, so CI must not do it.
        assert!(
            std::env::var_os("CI").is_none(),
            "UPDATE_OPENAPI must not be set in CI"
        );
        std::fs::write(path, &generated).expect("writing openapi/openapi.json");
        common::warn_past_capture("openapi/openapi.json regenerated, not checked");
        return;
    }
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        committed == generated,
        "openapi/openapi.json is stale: regenerate it with \
         `UPDATE_OPENAPI=1 cargo test --test api_openapi` and commit it"
    );
}

#[test]
fn every_route_is_documented_with_problem_errors() {
    let spec: serde_json::Value = serde_json::from_str(&silva::api::openapi_json()).unwrap();
    let paths = spec["paths"].as_object().unwrap();
    for route in [
        "/v1/trees",
        "/v1/trees/{id}",
        "/v1/trees/{id}/skeleton",
        "/v1/trees/{id}/lsystem",
        "/v1/trees/{id}/chaincode",
        "/v1/trees/{id}/mesh",
        "/v1/trees/{id}/cityjson",
        "/v1/cityjson",
        "/v1/collections/trees/items",
        "/v1/jobs/{id}",
        "/v1/jobs/{id}/retry",
        "/healthz",
        "/readyz",
        "/metrics",
    ] {
        assert!(paths.contains_key(route), "{route} is not documented");
    }
    let upload = &spec["paths"]["/v1/trees"]["post"];
    assert!(upload["responses"]["413"]["content"]["application/problem+json"].is_object());
    assert!(upload["security"].is_array());
}

/// The schema of parameter `name` of `method path` in the spec.
fn parameter<'a>(spec: &'a Value, path: &str, method: &str, name: &str) -> &'a Value {
    spec["paths"][path][method]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .map(|p| &p["schema"])
        .unwrap_or_else(|| panic!("{method} {path} has no parameter {name}"))
}

/// Found by schemathesis: the server answered statuses its spec did not
/// list (400 for an id that is not a UUID), and rejected requests the spec
/// allowed (an empty `mode` or `format`, `lod=4`, `limit=0`). Each bound
/// the spec states now holds on the server, on both sides of the bound.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_spec_documents_what_the_server_answers() {
    let spec: Value = serde_json::from_str(&silva::api::openapi_json()).unwrap();
    let db = TestDb::sqlite();
    let srv = TestServer::start(config(&db.url())).await;
    let none = uuid::Uuid::now_v7();

    // A malformed id: a documented problem+json 400 on every route.
    for (method, template) in [
        ("get", "/v1/trees/{id}"),
        ("delete", "/v1/trees/{id}"),
        ("get", "/v1/trees/{id}/skeleton"),
        ("get", "/v1/trees/{id}/lsystem"),
        ("get", "/v1/trees/{id}/chaincode"),
        ("get", "/v1/trees/{id}/mesh"),
        ("get", "/v1/trees/{id}/cityjson"),
        ("get", "/v1/jobs/{id}"),
        ("post", "/v1/jobs/{id}/retry"),
    ] {
        let url = srv.url(&template.replace("{id}", "null,null"));
        let req = match method {
            "get" => srv.http.get(url),
            "delete" => srv.http.delete(url),
            _ => srv.http.post(url),
        };
        assert_problem(req.send().await.unwrap(), 400).await;
        let documented = &spec["paths"][template][method]["responses"]["400"]["content"];
        assert!(
            documented["application/problem+json"].is_object(),
            "{method} {template} does not document its 400"
        );
    }

    // Enumerations: every listed value passes the query check (the missing
    // tree or the empty body answers), anything else is a 400.
    for download in ["mesh", "skeleton"] {
        let path = format!("/v1/trees/{{id}}/{download}");
        let formats = parameter(&spec, &path, "get", "format")["enum"]
            .as_array()
            .expect("download formats are an enum");
        assert!(!formats.is_empty(), "{download} formats");
        for format in formats {
            let format = format.as_str().unwrap();
            let res = srv
                .get(&format!("/v1/trees/{none}/{download}?format={format}"))
                .await;
            assert_problem(res, 404).await;
        }
        assert_problem(
            srv.get(&format!("/v1/trees/{none}/{download}?format="))
                .await,
            400,
        )
        .await;
    }
    let modes = parameter(&spec, "/v1/trees", "post", "mode")["enum"]
        .as_array()
        .expect("modes are an enum");
    assert!(!modes.is_empty(), "modes");
    for mode in modes {
        let mode = mode.as_str().unwrap();
        assert_problem(srv.upload(&format!("mode={mode}"), b"").await, 422).await;
    }
    assert_problem(srv.upload("mode=", b"").await, 400).await;

    // Ranges: the bounds pass, one past them is a 400.
    for (path, name, probe) in [
        (
            "/v1/trees/{id}/mesh",
            "lod",
            format!("/v1/trees/{none}/mesh?lod="),
        ),
        (
            "/v1/trees/{id}/cityjson",
            "lod",
            format!("/v1/trees/{none}/cityjson?lod="),
        ),
        (
            "/v1/trees/{id}/chaincode",
            "lod",
            format!("/v1/trees/{none}/chaincode?lod="),
        ),
        (
            "/v1/cityjson",
            "lod",
            "/v1/cityjson?bbox=0,0,1,1&lod=".to_owned(),
        ),
        ("/v1/trees", "limit", "/v1/trees?limit=".to_owned()),
        (
            "/v1/collections/trees/items",
            "limit",
            "/v1/collections/trees/items?limit=".to_owned(),
        ),
    ] {
        let schema = parameter(&spec, path, "get", name);
        let (min, max) = (
            schema["minimum"].as_i64().unwrap(),
            schema["maximum"].as_i64().unwrap(),
        );
        for ok in [min, max] {
            let status = srv.get(&format!("{probe}{ok}")).await.status().as_u16();
            assert!(status == 200 || status == 404, "{probe}{ok}: {status}");
        }
        for bad in [min - 1, max + 1] {
            assert_problem(srv.get(&format!("{probe}{bad}")).await, 400).await;
        }
    }
    assert_eq!(
        parameter(&spec, "/v1/trees", "post", "acquired")["format"],
        "date"
    );
    srv.stop().await;
    db.drop_db().await;
}

/// Found by schemathesis against `serve --read-requires-key`: every read
/// route answered a 401 its spec did not list. Each one now documents it,
/// with an optional key.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn read_routes_document_their_key() {
    let spec: Value = serde_json::from_str(&silva::api::openapi_json()).unwrap();
    let db = TestDb::sqlite();
    let mut cfg = config(&db.url());
    cfg.api_keys = vec!["s3cret".into()];
    cfg.read_requires_key = true;
    let srv = TestServer::start(cfg).await;
    let none = uuid::Uuid::now_v7();
    let mut reads = 0;
    for (template, item) in spec["paths"].as_object().unwrap() {
        let Some(read) = item.get("get").filter(|_| template.starts_with("/v1/")) else {
            continue;
        };
        let path = template.replace("{id}", &none.to_string());
        let path = if path == "/v1/cityjson" {
            "/v1/cityjson?bbox=0,0,1,1".into()
        } else {
            path
        };
        assert_problem(srv.get(&path).await, 401).await;
        assert!(
            read["responses"]["401"]["content"]["application/problem+json"].is_object(),
            "GET {template} does not document its 401"
        );
        let security = &read["security"];
        assert_eq!(
            security[0],
            serde_json::json!({}),
            "GET {template}: the key is optional"
        );
        assert!(
            security[1]["api_key"].is_array(),
            "GET {template}: {security}"
        );
        reads += 1;
    }
    assert_eq!(reads, 10);
    srv.stop().await;
    db.drop_db().await;
}
