-- An upload's Idempotency-Key header and a fingerprint of the request it
-- came with (SHA-256 of its metadata and body, hex): a client that sends the
-- same key again gets the first upload's tree and job instead of a second
-- scan; the same key with another request is refused. A key lives as long
-- as its scan.
ALTER TABLE scans ADD COLUMN idempotency_key TEXT;
ALTER TABLE scans ADD COLUMN request_sha256 TEXT;
CREATE UNIQUE INDEX scans_idempotency_key ON scans (idempotency_key)
    WHERE idempotency_key IS NOT NULL;
-- The key's lookup joins the scan's job.
CREATE INDEX jobs_scan ON jobs (scan_id);
