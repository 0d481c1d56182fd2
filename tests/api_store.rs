//! The job queue at the storage level, on both backends: leases expire and
//! are reclaimed, a worker that lost its lease cannot store a result, and a
//! job whose workers keep dying is failed instead of retried forever.

mod common;

use std::time::Duration;

use common::on_both;
use silva::store::{JobState, NewIngest, NewModel, Store};

fn upload() -> NewIngest {
    NewIngest {
        format: "xyz".into(),
        point_count: 3,
        cloud_laz: vec![1, 2, 3],
        options: "{}".into(),
        ..NewIngest::default()
    }
}

fn model() -> NewModel {
    NewModel {
        skeleton: "{}".into(),
        lsystem: "{}".into(),
        chaincode: vec![0],
        parameters: "{}".into(),
        metrics: "{}".into(),
        internodes: 1,
        location: [1.0, 2.0, 3.0],
        crs: None,
        height_m: 4.0,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn expired_leases_are_reclaimed_and_lost_leases_store_nothing() {
    on_both(|url| async move {
        let store = Store::connect(&url, 2).await.unwrap();
        let ingested = store.ingest(&upload()).await.unwrap();
        let short = Duration::from_millis(1);
        let a = store
            .claim_job("worker-a", short, 3)
            .await
            .unwrap()
            .unwrap();
        assert_eq!(
            (a.id, a.attempts, a.state()),
            (ingested.job_id, 1, JobState::Running)
        );
        tokio::time::sleep(Duration::from_millis(20)).await;

        // Worker a is presumed dead; b takes the job over.
        let long = Duration::from_secs(60);
        let b = store.claim_job("worker-b", long, 3).await.unwrap().unwrap();
        assert_eq!((b.id, b.attempts), (a.id, 2));
        assert!(
            store
                .claim_job("worker-c", long, 3)
                .await
                .unwrap()
                .is_none()
        );
        assert!(!store.heartbeat(a.id, "worker-a", long, 0.5).await.unwrap());
        assert!(!store.complete_job(&a, "worker-a", &model()).await.unwrap());
        assert!(!store.fail_job(a.id, "worker-a", "late").await.unwrap());
        assert!(store.heartbeat(b.id, "worker-b", long, 0.5).await.unwrap());
        assert!(store.complete_job(&b, "worker-b", &model()).await.unwrap());

        let job = store.job(b.id).await.unwrap().unwrap();
        assert_eq!(job.state(), JobState::Succeeded);
        let tree = store.tree(ingested.tree_id).await.unwrap().unwrap();
        assert_eq!(tree.model_id, job.model_id);
        assert_eq!(tree.location(), Some([1.0, 2.0, 3.0]));
        store.close().await;
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_whose_workers_keep_dying_fails() {
    on_both(|url| async move {
        let store = Store::connect(&url, 2).await.unwrap();
        let ingested = store.ingest(&upload()).await.unwrap();
        let short = Duration::from_millis(1);
        for attempt in 1..=2 {
            let job = store.claim_job("dies", short, 2).await.unwrap().unwrap();
            assert_eq!(job.attempts, attempt);
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert!(store.claim_job("next", short, 2).await.unwrap().is_none());
        let job = store.job(ingested.job_id).await.unwrap().unwrap();
        assert_eq!(job.state(), JobState::Failed);
        assert!(job.error.unwrap().contains("stopped 2 times"));

        // Released jobs (a stopping worker) are queued again at once.
        let retried = store.retry_job(job.id).await.unwrap().unwrap();
        assert_eq!(retried.state(), JobState::Queued);
        let long = Duration::from_secs(60);
        store.claim_job("stopping", long, 5).await.unwrap().unwrap();
        store.release_job("stopping").await.unwrap();
        let job = store.claim_job("next", long, 5).await.unwrap().unwrap();
        assert_eq!(job.attempts, 4);
        store.close().await;
    })
    .await;
}
