//! The committed OpenAPI document matches the code.
//!
//! Regenerate it with `UPDATE_OPENAPI=1 cargo test --test api_openapi` or
//! `silva serve --print-openapi > openapi/openapi.json`.

#[test]
fn committed_spec_is_current() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.json");
    let generated = silva::api::openapi_json();
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        std::fs::write(path, &generated).expect("writing openapi/openapi.json");
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
