/* Cost of the JSON layer against the core's evaluation, per node.
 *
 *   ntscontact_codec_bench [DISKS_PER_SIDE [NODES_PER_DISK [REPEATS [steps]]]]
 *
 * Builds a square packing of pressed polygonal disks as a JSON request, then
 * times each stage of ntsj_handle separately: strict scan, cJSON parse, decode
 * into nts_scene_def, nts_scene_create, nts_evaluate (forces + energy + virial),
 * and encoding the result (forces only, and forces + contacts). Prints the best
 * of REPEATS runs in ns per node. Figures go to docs/codec.md. With `steps`,
 * then a session's steps in process against the evaluation they make, at
 * equal work (session_steps; docs/benchmarks.md, "Session steps in
 * process"). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cjson/cJSON.h>

#include "codec_internal.h"

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void make_scene(ntsj_buf* b, int side, int m) {
    const double pi = 3.14159265358979323846;
    const double r = 1.0, pitch = 1.96; /* 2% overlap between neighbours */
    int i, j, k, id = 0;
    unsigned seed = 12345u;
    ntsj_buf_puts(b, "{\"version\":1,\"options\":{\"alpha\":0.2,\"penalty\":100.0,\"search_radius\":0.1},\"bodies\":[");
    for (i = 0; i < side; ++i) {
        for (j = 0; j < side; ++j) {
            double cx = pitch * j, cy = pitch * i;
            if (id) ntsj_buf_putc(b, ',');
            ntsj_buf_puts(b, "{\"id\":");
            ntsj_buf_int(b, id++);
            ntsj_buf_puts(b, ",\"nodes\":[");
            for (k = 0; k < m; ++k) {
                double a = 2.0 * pi * k / m, jit;
                seed = seed * 1103515245u + 12345u;
                jit = 1.0 + 0.002 * ((double)(seed >> 16 & 0x7fff) / 32767.0 - 0.5);
                if (k) ntsj_buf_putc(b, ',');
                ntsj_buf_putc(b, '[');
                ntsj_buf_double(b, cx + r * jit * cos(a));
                ntsj_buf_putc(b, ',');
                ntsj_buf_double(b, cy + r * jit * sin(a));
                ntsj_buf_putc(b, ']');
            }
            ntsj_buf_puts(b, "]}");
        }
    }
    ntsj_buf_puts(b, "]}");
}

static void sort_doubles(double* v, int n) { /* insertion sort: a handful of values */
    int k;
    for (k = 1; k < n; ++k) {
        double x = v[k];
        int j = k - 1;
        while (j >= 0 && v[j] > x) { v[j + 1] = v[j]; --j; }
        v[j + 1] = x;
    }
}

static double median_of(double* v, int n) {
    sort_doubles(v, n);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* A session step's cost in process against the evaluation it makes, at equal
 * work (issue 27 §3): the same positions, options and outputs, the same
 * search (keep = 0: a session without a kept list against nts_evaluate from
 * scratch; keep = 1: a session's kept list against nts_evaluate with a kept
 * list of its own, over the same frames). A step is the whole
 * ntsj_session_step: reading the positions (JSON text or raw float64), their
 * checks, the evaluation and the answer written (JSON, or raw forces); no
 * socket. Frames: every node moved by up to 1e-4 (a solver's small step),
 * each frame from the first positions, in rounds that time the evaluation,
 * the JSON step and the binary step in turn (which comes first rotates:
 * the first after a frame's text is written finds the caches colder), and
 * check that both steps answer the evaluation's energy (and the binary
 * one its forces, bit for bit). Prints the medians and each step's median
 * ratio to the evaluation of its round. */
static int session_steps(const ntsj_buf* req, long long nodes, int keep, int rounds) {
    ntsj_config cfg = ntsj_default_config();
    ntsj_session* ss = NULL;
    ntsj_response err;
    ntsj_fault fault;
    ntsj_scene js;
    nts_scene_def def;
    nts_scene* scene;
    nts_context* ctx = nts_context_create();
    nts_candidates* kc = keep ? nts_candidates_create(-1.0) : NULL;
    nts_result res;
    nts_error e = nts_error_none();
    ntsj_buf doc, text;
    const int n = (int)nodes;
    nts_vec2* base = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    nts_vec2* pos = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    double* raw = (double*)malloc(sizeof(double) * 2u * (size_t)n);
    double *te = (double*)malloc(sizeof(double) * (size_t)rounds), *tj = (double*)malloc(sizeof(double) * (size_t)rounds);
    double *tb = (double*)malloc(sizeof(double) * (size_t)rounds), *rj = (double*)malloc(sizeof(double) * (size_t)rounds);
    double* rb = (double*)malloc(sizeof(double) * (size_t)rounds);
    unsigned seed = 777u;
    cJSON* root;
    int k, i;
    cfg.max_bytes = (size_t)1 << 40;
    if (!ctx || (keep && !kc) || !base || !pos || !raw || !te || !tj || !tb || !rj || !rb) return 1;
    /* the same document with the session's kept list on or off */
    ntsj_buf_init(&doc);
    ntsj_buf_puts(&doc, keep ? "{\"session\":{\"keep_candidates\":true}," : "{\"session\":{\"keep_candidates\":false},");
    ntsj_buf_put(&doc, req->data + 1, req->len - 1);
    if (doc.oom || ntsj_session_create(doc.data, doc.len, &cfg, &ss, &err) != 0) {
        fprintf(stderr, "session: %s\n", doc.oom ? "out of memory" : err.body);
        return 1;
    }
    root = cJSON_ParseWithLengthOpts(req->data, req->len, NULL, 0);
    if (!root || ntsj_decode(root, &cfg, &js, &fault) != 0) return 1;
    cJSON_Delete(root);
    def = nts_default_scene_def();
    def.bodies = js.defs;
    def.body_count = js.body_count;
    if ((scene = nts_scene_create(&def, &e)) == NULL) return 1;
    memcpy(base, nts_scene_positions(scene), sizeof(nts_vec2) * (size_t)n);
    js.options.candidates = kc;
    for (k = -1; k < rounds; ++k) { /* (k = -1: warm, untimed) */
        ntsj_step st;
        ntsj_response answer[2];
        double t0, e_s = 0.0, j_s = 0.0, b_s = 0.0;
        int q;
        for (i = 0; i < n; ++i) {
            double dx, dy;
            seed = seed * 1103515245u + 12345u;
            dx = 1e-4 * ((double)(seed >> 16 & 0x7fff) / 32767.0 - 0.5);
            seed = seed * 1103515245u + 12345u;
            dy = 1e-4 * ((double)(seed >> 16 & 0x7fff) / 32767.0 - 0.5);
            pos[i] = nts_v2(base[i].x + dx, base[i].y + dy);
            raw[2 * i] = pos[i].x;
            raw[2 * i + 1] = pos[i].y;
        }
        ntsj_buf_init(&text);
        ntsj_buf_puts(&text, "{\"positions\":[");
        for (i = 0; i < n; ++i) {
            ntsj_buf_puts(&text, i ? ",[" : "[");
            ntsj_buf_double(&text, pos[i].x);
            ntsj_buf_putc(&text, ',');
            ntsj_buf_double(&text, pos[i].y);
            ntsj_buf_putc(&text, ']');
        }
        ntsj_buf_puts(&text, "]}");
        if (text.oom || nts_scene_update_positions(scene, pos, &e) != NTS_OK) return 1;
        /* the three in turn, each first in a third of the rounds (the one
         * after the frame's text is written finds the caches colder) */
        for (q = 0; q < 3; ++q) {
            const int which = (q + (k < 0 ? 0 : k)) % 3;
            if (which == 0) {
                t0 = now_s();
                if (nts_evaluate(ctx, scene, &js.options, &res, &e) != NTS_OK) {
                    fprintf(stderr, "evaluate: %s\n", e.message);
                    return 1;
                }
                e_s = now_s() - t0;
                continue;
            }
            memset(&st, 0, sizeof st);
            if (which == 1) {
                st.kind = NTSJ_STEP_JSON;
                st.body = text.data;
                st.length = text.len;
            } else {
                st.kind = NTSJ_STEP_BINARY;
                st.body = (const char*)raw;
                st.length = sizeof(double) * 2u * (size_t)n;
                st.answer_binary = 1;
            }
            t0 = now_s();
            if (ntsj_session_step(ss, &st, &cfg, &answer[which - 1]) != 0 || !answer[which - 1].ok) {
                fprintf(stderr, "step: %s\n", answer[which - 1].body);
                return 1;
            }
            if (which == 1) j_s = now_s() - t0;
            else b_s = now_s() - t0;
        }
        /* the same answer: the evaluation's energy in both, its forces' bits in the binary one */
        if (answer[0].summary.energy != res.summary.energy || answer[1].summary.energy != res.summary.energy ||
            memcmp(answer[1].body, res.forces, answer[1].length) != 0) {
            fprintf(stderr, "a step answered other forces than the evaluation\n");
            return 1;
        }
        ntsj_response_free(&answer[0]);
        ntsj_response_free(&answer[1]);
        ntsj_buf_free(&text);
        if (k >= 0) {
            te[k] = e_s;
            tj[k] = j_s;
            tb[k] = b_s;
            rj[k] = j_s / e_s;
            rb[k] = b_s / e_s;
        }
    }
    printf("%-26s %12.3f %12.1f\n", keep ? "kept evaluate (median)" : "evaluate (median)", median_of(te, rounds) * 1e3,
           median_of(te, rounds) * 1e9 / (double)nodes);
    printf("%-26s %12.3f %12.1f %10.2f  (median of the steps' ratios)\n", keep ? "kept step, JSON" : "step, JSON",
           median_of(tj, rounds) * 1e3, median_of(tj, rounds) * 1e9 / (double)nodes, median_of(rj, rounds));
    printf("%-26s %12.3f %12.1f %10.2f  (median of the steps' ratios)\n", keep ? "kept step, binary" : "step, binary",
           median_of(tb, rounds) * 1e3, median_of(tb, rounds) * 1e9 / (double)nodes, median_of(rb, rounds));
    ntsj_session_destroy(ss);
    nts_candidates_destroy(kc);
    nts_context_destroy(ctx);
    nts_scene_destroy(scene);
    ntsj_scene_free(&js);
    ntsj_buf_free(&doc);
    free(base);
    free(pos);
    free(raw);
    free(te);
    free(tj);
    free(tb);
    free(rj);
    free(rb);
    return 0;
}

#define STAGES 7
static const char* const stage_names[STAGES] = {"scan (strict RFC 8259)", "cJSON parse", "decode",
                                                "nts_scene_create", "nts_evaluate", "encode forces",
                                                "encode forces+contacts"};

int main(int argc, char** argv) {
    int side = argc > 1 ? atoi(argv[1]) : 32;
    int m = argc > 2 ? atoi(argv[2]) : 64;
    int repeats = argc > 3 ? atoi(argv[3]) : 5;
    ntsj_config cfg = ntsj_default_config();
    double best[STAGES];
    ntsj_buf req;
    long long nodes = (long long)side * side * m;
    int rep, i, contacts = 0;
    size_t out_bytes[2] = {0, 0};

    const int steps = argc > 4 && strcmp(argv[4], "steps") == 0;
    if (side < 1 || m < 3 || repeats < 1 || (argc > 4 && !steps) || argc > 5) {
        fprintf(stderr, "usage: %s [DISKS_PER_SIDE [NODES_PER_DISK [REPEATS [steps]]]]\n", argv[0]);
        return 2;
    }
    cfg.max_bytes = (size_t)1 << 40;
    for (i = 0; i < STAGES; ++i) best[i] = 1e300;
    ntsj_buf_init(&req);
    make_scene(&req, side, m);
    if (req.oom) return 1;

    for (rep = 0; rep < repeats; ++rep) {
        ntsj_fault fault;
        ntsj_scene s;
        nts_scene_def def;
        nts_scene* scene;
        nts_context* ctx;
        nts_result res;
        nts_error err = nts_error_none();
        ntsj_buf out;
        cJSON* root;
        double t[STAGES + 1];

        t[0] = now_s();
        if (ntsj_scan(req.data, req.len, cfg.max_depth, &fault) != 0) { fprintf(stderr, "scan: %s\n", fault.message); return 1; }
        t[1] = now_s();
        root = cJSON_ParseWithLengthOpts(req.data, req.len, NULL, 0);
        if (!root) return 1;
        t[2] = now_s();
        if (ntsj_decode(root, &cfg, &s, &fault) != 0) { fprintf(stderr, "decode: %s\n", fault.message); return 1; }
        t[3] = now_s();
        cJSON_Delete(root);
        t[3] += 0.0;
        {
            double t3b = now_s();
            def = nts_default_scene_def();
            def.bodies = s.defs;
            def.body_count = s.body_count;
            scene = nts_scene_create(&def, &err);
            if (!scene) { fprintf(stderr, "scene: %s\n", err.message); return 1; }
            t[4] = now_s() - (t3b - t[3]); /* do not count cJSON_Delete */
        }
        ctx = nts_context_create();
        s.options.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_CONTACTS;
        {
            double te = now_s();
            if (nts_evaluate(ctx, scene, &s.options, &res, &err) != 0) { fprintf(stderr, "evaluate: %s\n", err.message); return 1; }
            t[5] = t[4] + (now_s() - te);
        }
        contacts = res.contact_count;
        {
            double te = now_s();
            ntsj_buf_init(&out);
            s.options.outputs = NTS_OUT_FORCES;
            ntsj_encode_result(&out, &s, scene, &res, 0.0, 0);
            out_bytes[0] = out.len;
            ntsj_buf_free(&out);
            t[6] = t[5] + (now_s() - te);
            te = now_s();
            s.options.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
            ntsj_encode_result(&out, &s, scene, &res, 0.0, 0);
            out_bytes[1] = out.len;
            ntsj_buf_free(&out);
            t[7] = t[6] + (now_s() - te);
        }
        for (i = 0; i < STAGES; ++i)
            if (t[i + 1] - t[i] < best[i]) best[i] = t[i + 1] - t[i];
        nts_context_destroy(ctx);
        nts_scene_destroy(scene);
        ntsj_scene_free(&s);
    }
    printf("scene: %d bodies x %d nodes = %lld nodes, request %.1f MB, %d active contacts\n", side * side, m, nodes,
           (double)req.len / 1e6, contacts);
    printf("response: %.1f MB (forces), %.1f MB (forces+contacts)\n", (double)out_bytes[0] / 1e6,
           (double)out_bytes[1] / 1e6);
    printf("%-26s %12s %12s %10s\n", "stage (best of runs)", "ms", "ns/node", "x evaluate");
    for (i = 0; i < STAGES; ++i)
        printf("%-26s %12.3f %12.1f %10.2f\n", stage_names[i], best[i] * 1e3, best[i] * 1e9 / (double)nodes,
               best[i] / best[4]);
    /* What a solver loop pays per step for the evaluation alone: the median of
     * REPEATS evaluations on a warm context (its buffers grown), forces, energy
     * and virial only, as a session step evaluates. */
    {
        ntsj_fault fault;
        ntsj_scene s;
        nts_scene_def def;
        nts_scene* scene;
        nts_context* ctx = nts_context_create();
        nts_result res;
        nts_error err = nts_error_none();
        double* times = malloc(sizeof(double) * (size_t)(repeats > 0 ? repeats : 1));
        cJSON* root = cJSON_ParseWithLengthOpts(req.data, req.len, NULL, 0);
        int k;
        if (!root || !ctx || !times || ntsj_decode(root, &cfg, &s, &fault) != 0) return 1;
        cJSON_Delete(root);
        def = nts_default_scene_def();
        def.bodies = s.defs;
        def.body_count = s.body_count;
        scene = nts_scene_create(&def, &err);
        if (!scene) return 1;
        s.options.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
        if (nts_evaluate(ctx, scene, &s.options, &res, &err) != 0) return 1;
        for (k = 0; k < repeats; ++k) {
            double te = now_s();
            if (nts_evaluate(ctx, scene, &s.options, &res, &err) != 0) return 1;
            times[k] = now_s() - te;
        }
        sort_doubles(times, repeats);
        printf("%-26s %12.3f %12.1f\n", "warm evaluate (median)", times[repeats / 2] * 1e3,
               times[repeats / 2] * 1e9 / (double)nodes);
        {
            /* The same with the tangent (NTS_OUT_STIFFNESS), for docs/benchmarks.md. */
            double base = times[repeats / 2];
            s.options.outputs |= NTS_OUT_STIFFNESS;
            if (nts_evaluate(ctx, scene, &s.options, &res, &err) != 0) return 1;
            for (k = 0; k < repeats; ++k) {
                double te = now_s();
                if (nts_evaluate(ctx, scene, &s.options, &res, &err) != 0) return 1;
                times[k] = now_s() - te;
            }
            sort_doubles(times, repeats);
            printf("%-26s %12.3f %12.1f %10.2f  (%d triplets)\n", "warm + stiffness (median)",
                   times[repeats / 2] * 1e3, times[repeats / 2] * 1e9 / (double)nodes, times[repeats / 2] / base,
                   res.stiffness.count);
        }
        free(times);
        nts_context_destroy(ctx);
        nts_scene_destroy(scene);
        ntsj_scene_free(&s);
    }
    /* Session steps in process at equal work (issue 27 §3): at least 21
     * rounds, so that a median says something at small sizes. */
    if (steps) {
        printf("session steps in process, at equal work (median of %d rounds)\n", repeats < 21 ? 21 : repeats);
        if (session_steps(&req, nodes, 0, repeats < 21 ? 21 : repeats) != 0 ||
            session_steps(&req, nodes, 1, repeats < 21 ? 21 : repeats) != 0)
            return 1;
    }
    ntsj_buf_free(&req);
    return 0;
}
