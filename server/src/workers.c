/* A fixed set of evaluation threads fed by a FIFO of jobs (the pool model's
 * offload: a polling thread suspends the connection, a worker runs the codec,
 * then resumes the connection; see server.c). */
#include <stdlib.h>

#include "server.h"

static void* worker_main(void* arg) {
    ntsd_workers* w = arg;
    for (;;) {
        ntsd_job* job;
        pthread_mutex_lock(&w->lock);
        while (w->head == NULL && !w->stopping) pthread_cond_wait(&w->ready, &w->lock);
        if (w->head == NULL) { /* stopping and drained */
            pthread_mutex_unlock(&w->lock);
            return NULL;
        }
        job = w->head;
        w->head = job->next;
        if (w->head == NULL) w->tail = NULL;
        w->queued--;
        pthread_mutex_unlock(&w->lock);
        job->run(job->arg);
    }
}

int ntsd_workers_start(ntsd_workers* w, int count) {
    int i;
    w->head = w->tail = NULL;
    w->queued = 0;
    w->stopping = 0;
    w->count = 0;
    w->threads = calloc((size_t)count, sizeof *w->threads);
    if (w->threads == NULL) return -1;
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->ready, NULL);
    for (i = 0; i < count; i++) {
        if (pthread_create(&w->threads[i], NULL, worker_main, w) != 0) break;
        w->count++;
    }
    if (w->count == 0) {
        ntsd_workers_stop(w);
        return -1;
    }
    return 0;
}

void ntsd_workers_push(ntsd_workers* w, ntsd_job* job) {
    job->next = NULL;
    pthread_mutex_lock(&w->lock);
    if (w->tail != NULL)
        w->tail->next = job;
    else
        w->head = job;
    w->tail = job;
    w->queued++;
    pthread_cond_signal(&w->ready);
    pthread_mutex_unlock(&w->lock);
}

void ntsd_workers_stop(ntsd_workers* w) {
    int i;
    if (w->threads == NULL) return;
    pthread_mutex_lock(&w->lock);
    w->stopping = 1;
    pthread_cond_broadcast(&w->ready);
    pthread_mutex_unlock(&w->lock);
    for (i = 0; i < w->count; i++) pthread_join(w->threads[i], NULL);
    free(w->threads);
    w->threads = NULL;
    pthread_cond_destroy(&w->ready);
    pthread_mutex_destroy(&w->lock);
}
