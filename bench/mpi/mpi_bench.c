/* The distributed evaluation's figures (docs/distributed.md): under
 * mpirun -np P, a jittered packing of D disks of K nodes (pressed into each
 * other), bodies dealt to the ranks in blocks; the median of R evaluations
 * (after one warm-up) of ntsm_evaluate, its phases, the bytes each rank
 * sends, and the halo (the surface entries a rank evaluates beyond those it
 * owns); with -np 1 also nts_evaluate on the whole scene.
 * Between evaluations every node moves by 1e-4 (a solver's step), so the
 * decomposition is kept (SKIN < 0: the default skin) or made anew every
 * time (SKIN 0).
 * The host owns the disks by bands of rows (LAYOUT 0), by bands of columns
 * (LAYOUT 1): the library's slabs follow either; or dealt in turn, disk b
 * to rank b mod P (LAYOUT 2: no slab can follow the host, so that about
 * half of the contributions go to another rank on 2 ranks).
 * NTSM_BENCH_STEPS=1: each step's time, and whether it made the parts or
 * replayed its candidate lists, on stderr.
 * usage: mpi_bench DISKS NODES_PER_DISK REPEATS [THREADS [SKIN [LAYOUT]]] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/mpi.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static int cmp_double(const void* a, const void* b) {
    const double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

int main(int argc, char** argv) {
    int rank, size, disks, per, repeats, threads, side, b, k, rep, rebuilt = 0, layout, mine = 0;
    double skin;
    nts_vec2* nodes;
    nts_body_def* defs;
    int* ids;
    double* times;
    unsigned seed = 7u;
    ntsm_scene* m;
    nts_error err;
    nts_options opt = nts_default_options();
    ntsm_result r;
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    if (argc < 4) {
        if (rank == 0) fprintf(stderr, "usage: mpi_bench DISKS NODES_PER_DISK REPEATS [THREADS [SKIN [LAYOUT]]]\n");
        MPI_Finalize();
        return 2;
    }
    disks = atoi(argv[1]);
    per = atoi(argv[2]);
    repeats = atoi(argv[3]);
    threads = argc > 4 ? atoi(argv[4]) : 0;
    skin = argc > 5 ? atof(argv[5]) : -1.0;
    layout = argc > 6 ? atoi(argv[6]) : 0;
    side = (int)ceil(sqrt((double)disks));
    /* this rank's disks: a band of rows or of columns (a host's decomposition) */
    nodes = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)disks * (size_t)per + 1);
    defs = (nts_body_def*)calloc((size_t)disks + 1, sizeof(nts_body_def));
    ids = (int*)calloc((size_t)disks + 1, sizeof(int));
    times = (double*)calloc((size_t)repeats + 1, sizeof(double));
    for (b = 0; b < disks; ++b) {
        double jx, jy, rr, ph;
        seed = seed * 1664525u + 1013904223u;
        jx = 0.04 * ((double)(seed >> 8) / 16777216.0 - 0.5);
        seed = seed * 1664525u + 1013904223u;
        jy = 0.04 * ((double)(seed >> 8) / 16777216.0 - 0.5);
        seed = seed * 1664525u + 1013904223u;
        rr = 0.54 * (0.92 + 0.12 * (double)(seed >> 8) / 16777216.0);
        seed = seed * 1664525u + 1013904223u;
        ph = (double)(seed >> 8) / 16777216.0;
        if ((layout == 0   ? (long long)b * size / disks
             : layout == 1 ? (long long)(b % side) * size / side
                           : (long long)(b % size)) != rank)
            continue;
        for (k = 0; k < per; ++k) {
            nodes[(size_t)mine * per + k].x = (b % side) + 0.5 + jx + rr * cos(ph + 2 * M_PI * k / per);
            nodes[(size_t)mine * per + k].y = (b / side) + 0.5 + jy + rr * sin(ph + 2 * M_PI * k / per);
        }
        defs[mine].nodes = nodes + (size_t)mine * per;
        defs[mine].node_count = per;
        ids[mine++] = b;
    }
    m = ntsm_scene_create(MPI_COMM_WORLD, defs, ids, mine, 0.0, 0.0, nts_default_limits(), &err);
    if (m == NULL) {
        if (rank == 0) fprintf(stderr, "mpi_bench: %s\n", err.message);
        MPI_Finalize();
        return 1;
    }
    opt.threads = threads;
    ntsm_scene_set_skin(m, skin);
    if (ntsm_evaluate(m, &opt, &r, &err) != 0) { /* warm-up */
        if (rank == 0) fprintf(stderr, "mpi_bench: %s\n", err.message);
        MPI_Finalize();
        return 1;
    }
    {
        double ph[4] = {0, 0, 0, 0};
        for (rep = 0; rep < repeats; ++rep) {
            double t0;
            const size_t nn = (size_t)mine * (size_t)per;
            size_t i;
            for (i = 0; i < nn; ++i) nodes[i].x += rep % 2 ? -1e-4 : 1e-4;
            MPI_Barrier(MPI_COMM_WORLD);
            t0 = MPI_Wtime();
            ntsm_scene_update_positions(m, nodes, &err);
            ntsm_evaluate(m, &opt, &r, &err);
            rebuilt += r.stats.rebuilt;
            MPI_Barrier(MPI_COMM_WORLD);
            times[rep] = MPI_Wtime() - t0;
            if (rank == 0 && getenv("NTSM_BENCH_STEPS") != NULL) /* each step's time and whether it rebuilt */
                fprintf(stderr, "step %d %.4f rebuilt %d replayed %d\n", rep, times[rep], r.stats.rebuilt, r.stats.candidates_replayed);
            for (k = 0; k < 4; ++k) ph[k] += r.stats.seconds[k] / repeats;
        }
        qsort(times, (size_t)repeats, sizeof(double), cmp_double);
        {
            long long sent = r.stats.bytes_sent, maxsent = 0;
            int held = r.stats.part_entries, owned = r.stats.owned_slaves, mh = 0, mo = 0;
            double maxph[4];
            MPI_Reduce(&sent, &maxsent, 1, MPI_LONG_LONG, MPI_MAX, 0, MPI_COMM_WORLD);
            MPI_Reduce(&held, &mh, 1, MPI_INT, MPI_SUM, 0, MPI_COMM_WORLD);
            MPI_Reduce(&owned, &mo, 1, MPI_INT, MPI_SUM, 0, MPI_COMM_WORLD);
            MPI_Reduce(ph, maxph, 4, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
            if (getenv("NTSM_BENCH_RANKS") != NULL) /* each rank's own phases and load */
                fprintf(stderr, "rank %d bodies %d held_entries %d owned_slaves %d phases_s %.4f %.4f %.4f %.4f\n", rank, mine,
                        held, owned, ph[0], ph[1], ph[2], ph[3]);
            if (rank == 0)
                printf("rebuilt %d/%d ranks %d nodes %d contacts %d median_s %.4f min_s %.4f phases_s frame+slabs %.4f bodies %.4f "
                       "evaluate %.4f sums %.4f max_bytes_sent_per_rank %lld halo_fraction %.4f\n",
                       rebuilt, repeats, size, r.summary.surface_nodes, r.summary.contacts, times[repeats / 2], times[0], maxph[0],
                       maxph[1], maxph[2], maxph[3], maxsent, mo > 0 ? (double)(mh - mo) / mo : 0.0);
        }
    }
    if (size == 1 && getenv("NTSM_BENCH_NO_SERIAL") == NULL) { /* the same scene in one process, nts_evaluate */
        nts_scene_def def = nts_default_scene_def();
        nts_scene* whole;
        nts_context* ctx = nts_context_create();
        nts_result res;
        def.bodies = defs;
        def.body_count = disks;
        whole = nts_scene_create(&def, &err);
        nts_evaluate(ctx, whole, &opt, &res, &err);
        for (rep = 0; rep < repeats; ++rep) {
            const double t0 = MPI_Wtime();
            nts_evaluate(ctx, whole, &opt, &res, &err);
            times[rep] = MPI_Wtime() - t0;
        }
        qsort(times, (size_t)repeats, sizeof(double), cmp_double);
        printf("nts_evaluate whole scene: median_s %.4f min_s %.4f contacts %d\n", times[repeats / 2], times[0],
               res.summary.contacts);
        nts_scene_destroy(whole);
        nts_context_destroy(ctx);
    }
    ntsm_scene_destroy(m);
    free(nodes);
    free(defs);
    free(ids);
    free(times);
    MPI_Finalize();
    return 0;
}
