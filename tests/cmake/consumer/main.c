/* Two pressed squares through the installed library: the core directly, then
 * the codec on the same scene as JSON; prints the energies, which must agree. */
#include <stdio.h>
#include <string.h>

#include <ntscontact/codec.h>
#include <ntscontact/config.h>
#include <ntscontact/ntscontact.h>

int main(void) {
    static const nts_vec2 a[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}}, b[4] = {{0.95, 0.1}, {2, 0.1}, {2, 1.1}, {0.95, 1.1}};
    static const char json[] = "{\"options\":{\"penalty\":100,\"alpha\":0.2,\"search_radius\":0.2},\"bodies\":["
                               "{\"id\":\"a\",\"nodes\":[[0,0],[1,0],[1,1],[0,1]]},"
                               "{\"id\":\"b\",\"nodes\":[[0.95,0.1],[2,0.1],[2,1.1],[0.95,1.1]]}]}";
    nts_body_def bodies[2];
    nts_scene_def def = nts_default_scene_def();
    nts_options o = nts_default_options();
    nts_error err;
    nts_result r;
    nts_scene* s;
    nts_context* c = nts_context_create();
    ntsj_response resp;
    memset(bodies, 0, sizeof bodies);
    bodies[0].nodes = a;
    bodies[0].node_count = 4;
    bodies[1].nodes = b;
    bodies[1].node_count = 4;
    def.bodies = bodies;
    def.body_count = 2;
    s = nts_scene_create(&def, &err);
    o.penalty = 100.0;
    o.search_radius = 0.2;
    if (s == NULL || nts_evaluate(c, s, &o, &r, &err) != NTS_OK) return 1;
    printf("version %s openmp %d\n", NTS_VERSION_STRING, NTS_CONFIG_OPENMP);
    printf("core energy %.17g contacts %d\n", r.summary.energy, r.summary.contacts);
    if (ntsj_handle(json, sizeof json - 1, NULL, &resp) != 0 || !resp.ok) return 2;
    printf("codec %s", strstr(resp.body, "\"energy\"") ? "has energy\n" : "no energy\n");
    ntsj_response_free(&resp);
    nts_context_destroy(c);
    nts_scene_destroy(s);
    return 0;
}
