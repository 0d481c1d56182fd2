-- silva schema, PostgreSQL. Times are Unix milliseconds (BIGINT) so that both
-- backends compare leases and order rows identically; JSON documents are TEXT
-- because the service stores and serves them verbatim.

CREATE TABLE trees (
    id            UUID PRIMARY KEY,          -- UUIDv7: time-ordered, the cursor key
    external_id   TEXT,                      -- the inventory's own id, unique when given
    species       TEXT,
    crs           TEXT,
    x             DOUBLE PRECISION,          -- trunk base, absolute, in `crs` units;
    y             DOUBLE PRECISION,          -- NULL until the first model exists
    z             DOUBLE PRECISION,
    height_m      DOUBLE PRECISION,
    metrics       TEXT,                      -- JSON object of the current model
    model_id      UUID,                      -- current model
    version       BIGINT NOT NULL DEFAULT 1, -- bumped on every change (ETag)
    created_at_ms BIGINT NOT NULL,
    updated_at_ms BIGINT NOT NULL
);
CREATE UNIQUE INDEX trees_external_id ON trees (external_id) WHERE external_id IS NOT NULL;
-- bbox queries: a range scan on x narrowed by y (no PostGIS needed).
CREATE INDEX trees_location ON trees (x, y);
CREATE INDEX trees_species ON trees (species);
CREATE INDEX trees_height ON trees (height_m);

CREATE TABLE scans (
    id            UUID PRIMARY KEY,
    tree_id       UUID NOT NULL REFERENCES trees (id) ON DELETE CASCADE,
    acquired      TEXT,                      -- ISO 8601 date of acquisition
    source        TEXT,                      -- e.g. "TLS", "AHN4"
    format        TEXT NOT NULL,             -- format of the upload
    point_count   BIGINT NOT NULL,
    cloud_laz     BYTEA NOT NULL,            -- the raw cloud, LAZ-compressed
    created_at_ms BIGINT NOT NULL
);
CREATE INDEX scans_tree ON scans (tree_id);

CREATE TABLE models (
    id            UUID PRIMARY KEY,
    tree_id       UUID NOT NULL REFERENCES trees (id) ON DELETE CASCADE,
    scan_id       UUID NOT NULL REFERENCES scans (id) ON DELETE CASCADE,
    skeleton      TEXT NOT NULL,             -- silva skeleton JSON
    lsystem       TEXT NOT NULL,             -- LsJSON
    chaincode     BYTEA NOT NULL,            -- compressed DBF6 chain code
    parameters    TEXT NOT NULL,             -- JSON: mode, options, error bounds
    metrics       TEXT NOT NULL,             -- JSON
    internodes    BIGINT NOT NULL,
    created_at_ms BIGINT NOT NULL
);
CREATE INDEX models_tree ON models (tree_id);

CREATE TABLE jobs (
    id               UUID PRIMARY KEY,
    kind             TEXT NOT NULL,          -- "reconstruct"
    state            TEXT NOT NULL,          -- queued | running | succeeded | failed
    progress         DOUBLE PRECISION NOT NULL DEFAULT 0,
    attempts         INTEGER NOT NULL DEFAULT 0, -- executions started
    error            TEXT,
    lease_owner      TEXT,
    lease_expires_ms BIGINT,
    tree_id          UUID NOT NULL REFERENCES trees (id) ON DELETE CASCADE,
    scan_id          UUID NOT NULL REFERENCES scans (id) ON DELETE CASCADE,
    options          TEXT NOT NULL,          -- JSON reconstruction options
    model_id         UUID,
    created_at_ms    BIGINT NOT NULL,
    updated_at_ms    BIGINT NOT NULL,
    started_at_ms    BIGINT,
    finished_at_ms   BIGINT
);
CREATE INDEX jobs_claim ON jobs (state, created_at_ms);
