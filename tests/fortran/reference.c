/* The C side of tests/fortran/test_fortran.f90.
 *
 * Reads a bundled example scene (a JSON file of examples/) with cJSON into plain
 * arrays that the Fortran program builds its scene from, and evaluates the
 * same scene through the C API directly: the reference that the Fortran
 * module's answer must equal bit for bit. Its options are its own
 * nts_options, set here from the file, never the Fortran program's struct,
 * so that a mirrored layout that differs cannot give both sides the same
 * wrong options. Also the C tables (status codes, output bits, warnings) that
 * the module's constants are checked against.
 *
 * It reads the few keys the examples use and refuses any other, so that the
 * test never passes on a scene it half read. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>
#include <ntscontact/ntscontact.h>

typedef struct file_body {
    int node_count, triangle_count, loop_count, loop_length;
    nts_vec2* nodes;
    int* triangles;  /* 3 a triangle, 0-based as the file */
    int* loop_nodes; /* 0-based */
    int* loop_start; /* loop_count + 1 */
} file_body;

static struct {
    int body_count, node_count;
    file_body* bodies;
    double alpha, penalty, search_radius, lx, ly;
} file;

static struct {
    nts_scene* scene;
    nts_context* ctx;
    nts_result res;
} ref;

/* A sequence of steps with friction (ftest_friction_step): the scene, its
 * context and its history kept from step to step, as a solver keeps them. */
static struct {
    nts_scene* scene;
    nts_context* ctx;
    nts_history* history;
    nts_result res;
} fric;

/* The functions the Fortran program binds to (no header: only it calls them). */
int ftest_load(const char* path);
int ftest_body_count(void);
void ftest_body_sizes(int b, int* nodes, int* triangles, int* loops, int* loop_length);
void ftest_body_arrays(int b, double* xy, int* triangles, int* loop_nodes, int* loop_start);
void ftest_scene_options(double* alpha, double* penalty, double* search_radius, double* lx, double* ly);
int ftest_reference(const double* positions);
void ftest_reference_summary(double* energy, double* virial, int* contacts, double* max_penetration);
void ftest_reference_forces(double* xy);
int ftest_reference_triplet_count(void);
void ftest_reference_triplets(int* rows, int* cols, double* values);
int ftest_status_table(int* values, int max);
int ftest_output_table(int* bits, int max);
int ftest_warning_table(int* values, int max);
int ftest_friction_step(const double* positions, double friction, int commit);
void ftest_friction_out(double* xy, double* sums, int* counts);
int ftest_surface_node_count(void);
int ftest_reference_record_count(int gaps);
void ftest_reference_record(int gaps, int k, int* ints, double* reals);
void ftest_kind_state_values(int* values);
void ftest_free(void);

static int refuse(const char* what, const char* name) {
    fprintf(stderr, "reference.c: %s%s\n", what, name ? name : "");
    return -1;
}

static char* read_all(const char* path) {
    FILE* f = fopen(path, "rb");
    char* text = NULL;
    long n;
    if (f == NULL) return NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0 &&
        (text = (char*)malloc((size_t)n + 1)) != NULL) {
        if (fread(text, 1, (size_t)n, f) != (size_t)n) {
            free(text);
            text = NULL;
        } else {
            text[n] = '\0';
        }
    }
    fclose(f);
    return text;
}

/* An array of `width`-number arrays into out (n * width values). */
static int read_tuples(const cJSON* a, int width, double* out) {
    const cJSON* row;
    int k = 0;
    cJSON_ArrayForEach(row, a) {
        const cJSON* x;
        int j = 0;
        if (!cJSON_IsArray(row) || cJSON_GetArraySize(row) != width) return -1;
        cJSON_ArrayForEach(x, row) {
            if (!cJSON_IsNumber(x)) return -1;
            out[(size_t)k * (size_t)width + (size_t)j++] = x->valuedouble;
        }
        ++k;
    }
    return 0;
}

static int read_body(const cJSON* jb, file_body* b) {
    const cJSON* item;
    const cJSON* nodes = cJSON_GetObjectItemCaseSensitive(jb, "nodes");
    const cJSON* tri = cJSON_GetObjectItemCaseSensitive(jb, "triangles");
    const cJSON* loops = cJSON_GetObjectItemCaseSensitive(jb, "loops");
    cJSON_ArrayForEach(item, jb) {
        if (strcmp(item->string, "id") != 0 && strcmp(item->string, "nodes") != 0 &&
            strcmp(item->string, "triangles") != 0 && strcmp(item->string, "loops") != 0)
            return refuse("a body key this test does not read: ", item->string);
    }
    if (!cJSON_IsArray(nodes)) return refuse("a body without nodes", NULL);
    b->node_count = cJSON_GetArraySize(nodes);
    b->nodes = (nts_vec2*)calloc((size_t)b->node_count + 1, sizeof(nts_vec2));
    if (b->nodes == NULL || read_tuples(nodes, 2, &b->nodes[0].x) != 0) return refuse("bad nodes", NULL);
    if (tri != NULL) {
        double* t;
        int k;
        b->triangle_count = cJSON_GetArraySize(tri);
        t = (double*)calloc((size_t)b->triangle_count * 3 + 1, sizeof(double));
        b->triangles = (int*)calloc((size_t)b->triangle_count * 3 + 1, sizeof(int));
        if (t == NULL || b->triangles == NULL || read_tuples(tri, 3, t) != 0) {
            free(t);
            return refuse("bad triangles", NULL);
        }
        for (k = 0; k < 3 * b->triangle_count; ++k) b->triangles[k] = (int)t[k];
        free(t);
    }
    if (loops != NULL) {
        const cJSON* loop;
        int l = 0, k = 0;
        b->loop_count = cJSON_GetArraySize(loops);
        cJSON_ArrayForEach(loop, loops) b->loop_length += cJSON_GetArraySize(loop);
        b->loop_nodes = (int*)calloc((size_t)b->loop_length + 1, sizeof(int));
        b->loop_start = (int*)calloc((size_t)b->loop_count + 1, sizeof(int));
        if (b->loop_nodes == NULL || b->loop_start == NULL) return refuse("out of memory", NULL);
        cJSON_ArrayForEach(loop, loops) {
            const cJSON* x;
            b->loop_start[l++] = k;
            cJSON_ArrayForEach(x, loop) {
                if (!cJSON_IsNumber(x)) return refuse("bad loops", NULL);
                b->loop_nodes[k++] = x->valueint;
            }
        }
        b->loop_start[l] = k;
    }
    return 0;
}

static int read_options(const cJSON* o) {
    const cJSON* item;
    nts_options d = nts_default_options();
    file.alpha = d.alpha;
    file.penalty = d.penalty;
    file.search_radius = d.search_radius;
    cJSON_ArrayForEach(item, o) {
        const char* k = item->string;
        if (strcmp(k, "alpha") == 0 && cJSON_IsNumber(item)) {
            file.alpha = item->valuedouble;
        } else if (strcmp(k, "penalty") == 0 && cJSON_IsNumber(item)) {
            file.penalty = item->valuedouble;
        } else if (strcmp(k, "search_radius") == 0 && cJSON_IsNumber(item)) {
            file.search_radius = item->valuedouble;
        } else if (strcmp(k, "periodic") == 0) {
            const cJSON* lx = cJSON_GetObjectItemCaseSensitive(item, "lx");
            const cJSON* ly = cJSON_GetObjectItemCaseSensitive(item, "ly");
            if (!cJSON_IsNumber(lx) || !cJSON_IsNumber(ly)) return refuse("bad periodic box", NULL);
            file.lx = lx->valuedouble;
            file.ly = ly->valuedouble;
        } else if (strcmp(k, "outputs") != 0) { /* the test chooses its own outputs */
            return refuse("an option this test does not read: ", k);
        }
    }
    return 0;
}

int ftest_load(const char* path) {
    char* text = read_all(path);
    cJSON* doc = text ? cJSON_Parse(text) : NULL;
    const cJSON *bodies, *jb;
    int rc = 0, b = 0;
    free(text);
    ftest_free();
    if (doc == NULL) return refuse("cannot read or parse ", path);
    bodies = cJSON_GetObjectItemCaseSensitive(doc, "bodies");
    if (!cJSON_IsArray(bodies) || (rc = read_options(cJSON_GetObjectItemCaseSensitive(doc, "options"))) != 0) {
        cJSON_Delete(doc);
        return rc != 0 ? rc : refuse("no bodies in ", path);
    }
    file.body_count = cJSON_GetArraySize(bodies);
    file.bodies = (file_body*)calloc((size_t)file.body_count + 1, sizeof(file_body));
    if (file.bodies == NULL) rc = refuse("out of memory", NULL);
    cJSON_ArrayForEach(jb, bodies) {
        if (rc != 0) break;
        rc = read_body(jb, &file.bodies[b]);
        file.node_count += file.bodies[b++].node_count;
    }
    cJSON_Delete(doc);
    return rc;
}

int ftest_body_count(void) { return file.body_count; }

void ftest_body_sizes(int b, int* nodes, int* triangles, int* loops, int* loop_length) {
    const file_body* fb = &file.bodies[b];
    *nodes = fb->node_count;
    *triangles = fb->triangle_count;
    *loops = fb->loop_count;
    *loop_length = fb->loop_length;
}

void ftest_body_arrays(int b, double* xy, int* triangles, int* loop_nodes, int* loop_start) {
    const file_body* fb = &file.bodies[b];
    memcpy(xy, fb->nodes, sizeof(nts_vec2) * (size_t)fb->node_count);
    if (fb->triangle_count > 0) memcpy(triangles, fb->triangles, sizeof(int) * 3 * (size_t)fb->triangle_count);
    if (fb->loop_count > 0) {
        memcpy(loop_nodes, fb->loop_nodes, sizeof(int) * (size_t)fb->loop_length);
        memcpy(loop_start, fb->loop_start, sizeof(int) * ((size_t)fb->loop_count + 1));
    }
}

void ftest_scene_options(double* alpha, double* penalty, double* search_radius, double* lx, double* ly) {
    *alpha = file.alpha;
    *penalty = file.penalty;
    *search_radius = file.search_radius;
    *lx = file.lx;
    *ly = file.ly;
}

/* A scene of the file's bodies at `positions` (2 * node_count doubles,
 * global order; NULL: the file's own), or NULL with *err set. */
static nts_scene* file_scene(const double* positions, nts_error* err) {
    nts_scene_def def = nts_default_scene_def();
    nts_body_def* defs = (nts_body_def*)calloc((size_t)file.body_count + 1, sizeof(nts_body_def));
    nts_scene* scene;
    int b, offset = 0;
    if (defs == NULL) {
        err->code = NTS_ENOMEM;
        return NULL;
    }
    for (b = 0; b < file.body_count; ++b) {
        const file_body* fb = &file.bodies[b];
        defs[b].nodes = positions ? (const nts_vec2*)(const void*)(positions + 2 * offset) : fb->nodes;
        defs[b].node_count = fb->node_count;
        defs[b].triangles = fb->triangles;
        defs[b].triangle_count = fb->triangle_count;
        defs[b].loop_nodes = fb->loop_nodes;
        defs[b].loop_start = fb->loop_start;
        defs[b].loop_count = fb->loop_count;
        offset += fb->node_count;
    }
    def.bodies = defs;
    def.body_count = file.body_count;
    def.lx = file.lx;
    def.ly = file.ly;
    scene = nts_scene_create(&def, err);
    free(defs);
    return scene;
}

/* A fresh scene of the file's bodies at `positions` (NULL: the file's own),
 * evaluated with the file's options and outputs forces, energy, virial and
 * stiffness. Returns the status. */
int ftest_reference(const double* positions) {
    nts_options opt = nts_default_options();
    nts_error err;
    int rc;
    nts_scene_destroy(ref.scene);
    if ((ref.scene = file_scene(positions, &err)) == NULL) return err.code;
    if (ref.ctx == NULL && (ref.ctx = nts_context_create()) == NULL) return NTS_ENOMEM;
    opt.alpha = file.alpha;
    opt.penalty = file.penalty;
    opt.search_radius = file.search_radius;
    opt.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_STIFFNESS | NTS_OUT_CONTACTS | NTS_OUT_GAPS;
    rc = nts_evaluate(ref.ctx, ref.scene, &opt, &ref.res, &err);
    if (rc != NTS_OK) fprintf(stderr, "reference.c: %s: %s\n", nts_status_name(rc), err.message);
    return rc;
}

/* One step of a sequence with friction coefficient `friction`: the
 * sequence's scene (created at the first step's positions) given
 * `positions` and evaluated from its history (forces, energy, virial), and
 * with `commit` the step's anchors made the history. Returns the status. */
int ftest_friction_step(const double* positions, double friction, int commit) {
    nts_options opt = nts_default_options();
    nts_error err;
    int rc;
    if (fric.scene == NULL && (fric.scene = file_scene(positions, &err)) == NULL) return err.code;
    if (fric.ctx == NULL && (fric.ctx = nts_context_create()) == NULL) return NTS_ENOMEM;
    if (fric.history == NULL && (fric.history = nts_history_create()) == NULL) return NTS_ENOMEM;
    opt.alpha = file.alpha;
    opt.penalty = file.penalty;
    opt.search_radius = file.search_radius;
    opt.friction = friction;
    opt.history = fric.history;
    opt.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    rc = nts_evaluate_positions(fric.ctx, fric.scene, (const nts_vec2*)(const void*)positions, &opt, &fric.res, &err);
    if (rc != NTS_OK) fprintf(stderr, "reference.c: %s: %s\n", nts_status_name(rc), err.message);
    if (rc == NTS_OK && commit) rc = nts_history_commit(fric.history, &fric.res);
    return rc;
}

/* The last friction step's forces, its sums (energy, dissipation, the
 * virial's xx, yy, xy, yx) and counts (contacts, sticking, slipping, the
 * history's anchors). */
void ftest_friction_out(double* xy, double* sums, int* counts) {
    const nts_summary* su = &fric.res.summary;
    memcpy(xy, fric.res.forces, sizeof(nts_vec2) * (size_t)file.node_count);
    sums[0] = su->energy;
    sums[1] = su->dissipation;
    sums[2] = su->virial.xx;
    sums[3] = su->virial.yy;
    sums[4] = su->virial.xy;
    sums[5] = su->virial.yx;
    counts[0] = su->contacts;
    counts[1] = su->sticking;
    counts[2] = su->slipping;
    nts_history_anchors(fric.history, &counts[3]);
}

void ftest_reference_summary(double* energy, double* virial, int* contacts, double* max_penetration) {
    *energy = ref.res.summary.energy;
    virial[0] = ref.res.summary.virial.xx;
    virial[1] = ref.res.summary.virial.yy;
    virial[2] = ref.res.summary.virial.xy;
    virial[3] = ref.res.summary.virial.yx;
    *contacts = ref.res.summary.contacts;
    *max_penetration = ref.res.summary.max_penetration;
}

void ftest_reference_forces(double* xy) {
    memcpy(xy, ref.res.forces, sizeof(nts_vec2) * (size_t)file.node_count);
}

int ftest_reference_triplet_count(void) { return ref.res.stiffness.count; }

void ftest_reference_triplets(int* rows, int* cols, double* values) {
    const nts_triplets* t = &ref.res.stiffness;
    if (t->count == 0) return;
    memcpy(rows, t->rows, sizeof(int) * (size_t)t->count);
    memcpy(cols, t->cols, sizeof(int) * (size_t)t->count);
    memcpy(values, t->values, sizeof(double) * (size_t)t->count);
}

/* The reference's contacts (gaps 0) or gaps (1): how many, and record k's
 * fields as C has them (0-based): ints slave body, slave node, master body,
 * kind, master count, master nodes (3), state; reals weights (3), param,
 * gap, normal, point, force (2 each), virial (xx, yy, xy, yx), penalty,
 * tangential force (2), slip. */
int ftest_reference_record_count(int gaps) { return gaps ? ref.res.gap_count : ref.res.contact_count; }

void ftest_reference_record(int gaps, int k, int* ints, double* reals) {
    const nts_contact* c = gaps ? &ref.res.gaps[k] : &ref.res.contacts[k];
    const double r[22] = {c->weights[0], c->weights[1], c->weights[2], c->param, c->gap, c->normal.x, c->normal.y,
                          c->point.x, c->point.y, c->force.x, c->force.y, c->virial.xx, c->virial.yy, c->virial.xy,
                          c->virial.yx, c->penalty, c->tangential_force.x, c->tangential_force.y, c->slip, 0.0, 0.0,
                          0.0};
    ints[0] = c->slave_body;
    ints[1] = c->slave_node;
    ints[2] = c->master_body;
    ints[3] = (int)c->kind;
    ints[4] = c->master_count;
    ints[5] = c->master_nodes[0];
    ints[6] = c->master_nodes[1];
    ints[7] = c->master_nodes[2];
    ints[8] = c->state;
    memcpy(reals, r, sizeof(double) * 19);
}

/* geometry.h's kinds and ntscontact.h's friction states, in order. */
void ftest_kind_state_values(int* values) {
    values[0] = NTS_KIND_SEGMENT;
    values[1] = NTS_KIND_CORNER;
    values[2] = NTS_KIND_VERTEX;
    values[3] = NTS_FRICTIONLESS;
    values[4] = NTS_STICK;
    values[5] = NTS_SLIP;
}

/* The reference scene's nodes on loops (nts_scene_surface_node_count). */
int ftest_surface_node_count(void) { return nts_scene_surface_node_count(ref.scene); }

/* The tables in their C order; each returns how many rows it has (and
 * writes at most `max`), so the Fortran side sees a row it lacks too. */
int ftest_status_table(int* values, int max) {
    int n = 0;
#define FTEST_XX_(e, v, name, msg) \
    if (n < max) values[n] = NTS_E##e; \
    ++n;
    NTS_ERRNO_MAP(FTEST_XX_)
#undef FTEST_XX_
    return n;
}

int ftest_output_table(int* bits, int max) {
    int n = 0;
#define FTEST_XX_(ID, bit, name, result, records) \
    if (n < max) bits[n] = (int)NTS_OUT_##ID;    \
    ++n;
    NTS_OUTPUT_MAP(FTEST_XX_)
#undef FTEST_XX_
    if (n < max) bits[n] = (int)NTS_OUT_ALL;
    return n + 1;
}

int ftest_warning_table(int* values, int max) {
    int n = 0;
#define FTEST_XX_(e, v, name, msg) \
    if (n < max) values[n] = NTS_WARN_##e; \
    ++n;
    NTS_WARNING_MAP(FTEST_XX_)
#undef FTEST_XX_
    return n;
}

void ftest_free(void) {
    int b;
    for (b = 0; b < file.body_count && file.bodies; ++b) {
        free(file.bodies[b].nodes);
        free(file.bodies[b].triangles);
        free(file.bodies[b].loop_nodes);
        free(file.bodies[b].loop_start);
    }
    free(file.bodies);
    memset(&file, 0, sizeof file);
    nts_scene_destroy(ref.scene);
    nts_context_destroy(ref.ctx);
    memset(&ref, 0, sizeof ref);
    nts_scene_destroy(fric.scene);
    nts_context_destroy(fric.ctx);
    nts_history_destroy(fric.history);
    memset(&fric, 0, sizeof fric);
}
