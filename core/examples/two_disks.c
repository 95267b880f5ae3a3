/* The core's C API in one program: two disks of radius 1 (32 nodes each)
 * pressed together; prints the active contacts, the energy, the virial and
 * each contact (kind, gap, normal, force). Built as build/bin/two_disks with
 * the rest (core/CMakeLists.txt); the README's "The core in C" walks through
 * the same calls. */
#include <stdio.h>
#include <string.h>

#include <ntscontact/ntscontact.h>

#define NODES 32

int main(void) {
    nts_vec2 a[NODES], b[NODES];
    nts_body_def bodies[2];
    nts_scene_def def = nts_default_scene_def();
    nts_options opt = nts_default_options();
    nts_error err;
    nts_result res;
    nts_scene* scene;
    nts_context* ctx;
    const double pi = 3.14159265358979323846, overlap = 0.05;
    int i, k;

    for (i = 0; i < NODES; ++i) {
        double th = 2.0 * pi * i / NODES;
        a[i] = nts_v2(cos(th), sin(th));
        b[i] = nts_v2(2.0 - overlap + cos(th + pi / NODES), sin(th + pi / NODES));
    }
    /* Every field zero first: no loops (the nodes are one loop), no triangles,
     * the body's own alpha unset, role both (master and slave), ... */
    memset(bodies, 0, sizeof bodies);
    for (k = 0; k < 2; ++k) {
        bodies[k].nodes = k == 0 ? a : b;
        bodies[k].node_count = NODES;
    }
    def.bodies = bodies;
    def.body_count = 2;
    scene = nts_scene_create(&def, &err);
    if (scene == NULL) {
        fprintf(stderr, "scene: %s: %s\n", nts_status_name(err.code), err.message);
        return 1;
    }
    ctx = nts_context_create();
    opt.penalty = 100.0;
    opt.outputs = NTS_OUT_ALL;
    if (ctx == NULL || nts_evaluate(ctx, scene, &opt, &res, &err) != NTS_OK) {
        fprintf(stderr, "evaluate: %s: %s\n", nts_status_name(err.code), err.message);
        return 1;
    }
    printf("two disks of radius 1, %d nodes each, overlap %.3g, alpha %.2g, penalty %.0f\n", NODES, overlap,
           opt.alpha, opt.penalty);
    printf("active contacts %d, energy %.6e, max penetration %.6e\n", res.summary.contacts, res.summary.energy,
           res.summary.max_penetration);
    printf("virial xx %.6e yy %.6e xy %.6e\n", res.summary.virial.xx, res.summary.virial.yy, res.summary.virial.xy);
    printf("%-6s %-5s %-8s %-12s %-24s %s\n", "slave", "node", "kind", "gap", "normal", "force on slave");
    for (i = 0; i < res.contact_count; ++i) {
        const nts_contact* c = &res.contacts[i];
        static const char* kinds[] = {"segment", "corner", "vertex"};
        printf("%-6d %-5d %-8s %-12.4e (%+.4f, %+.4f)       (%+.4e, %+.4e)\n", c->slave_body, c->slave_node,
               kinds[c->kind], c->gap, c->normal.x, c->normal.y, c->force.x, c->force.y);
    }
    nts_context_destroy(ctx);
    nts_scene_destroy(scene);
    return 0;
}
