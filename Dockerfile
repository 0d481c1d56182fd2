# syntax=docker/dockerfile:1
# silva: multi-stage build. The builder compiles the release binary; the
# runtime image holds only that binary and runs as an unprivileged user.
#
#   docker build -t silva .
#   docker run -p 8080:8080 -e SILVA_LISTEN=0.0.0.0:8080 silva

FROM rust:1-bookworm AS builder
WORKDIR /src
COPY . .
# BuildKit caches keep the registry and compiled dependencies between builds.
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked --bin silva \
    && cp target/release/silva /usr/local/bin/silva

FROM debian:bookworm-slim AS runtime
RUN apt-get update \
    && apt-get install -y --no-install-recommends ca-certificates curl \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --uid 10001 --home-dir /var/lib/silva --create-home silva
COPY --from=builder /usr/local/bin/silva /usr/local/bin/silva
USER silva
WORKDIR /var/lib/silva
# Listen on all interfaces inside the container; the SQLite default lands in
# /var/lib/silva (a volume) unless DATABASE_URL points at PostgreSQL.
ENV SILVA_LISTEN=0.0.0.0:8080
EXPOSE 8080
VOLUME ["/var/lib/silva"]
HEALTHCHECK --interval=10s --timeout=3s --start-period=5s --retries=3 \
    CMD curl -fsS http://127.0.0.1:8080/readyz || exit 1
ENTRYPOINT ["silva"]
CMD ["serve"]
