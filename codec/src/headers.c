/* The summary of a binary session answer as header pairs (codec.h,
 * ntsj_binary_headers_of): one place for the text the daemon sends and the
 * in-process engine hands to the same reader. */
#include <assert.h>
#include <stdio.h>
#include <string.h>

#include "codec_internal.h"

/* Append a pair; the value is written by the caller into the slot returned. */
static char* add(ntsj_binary_headers* h, const char* name) {
    char* v;
    assert(h->count < NTSJ_BINARY_HEADERS_MAX);
    h->names[h->count] = name;
    v = h->values[h->count++];
    v[0] = '\0';
    return v;
}

static void add_int(ntsj_binary_headers* h, const char* name, long long value) {
    snprintf(add(h, name), sizeof h->values[0], "%lld", value);
}

static void add_double(ntsj_binary_headers* h, const char* name, double value) {
    ntsj_format_double(add(h, name), value);
}

void ntsj_binary_headers_of(const ntsj_response* r, ntsj_binary_headers* h) {
    const nts_summary* sm = &r->summary;
    char* v;
    size_t k;
    int w;
    memset(h, 0, sizeof *h);
    add_double(h, "NTS-Energy", sm->energy);
    v = add(h, "NTS-Virial");
    k = (size_t)ntsj_format_double(v, sm->virial.xx);
    v[k++] = ',';
    k += (size_t)ntsj_format_double(v + k, sm->virial.yy);
    v[k++] = ',';
    k += (size_t)ntsj_format_double(v + k, sm->virial.xy);
    if (r->friction) { /* not symmetric with friction (docs/model.md (28)): xx,yy,xy,yx */
        v[k++] = ',';
        ntsj_format_double(v + k, sm->virial.yx);
    }
    add_int(h, "NTS-Contacts", sm->contacts);
    add_double(h, "NTS-Max-Penetration", sm->max_penetration);
    add_double(h, "NTS-Elapsed-Ms", r->elapsed_ms);
    add_int(h, "NTS-Gaps", sm->gaps);
    add_int(h, "NTS-Loops-Reversed", sm->loops_reversed);
    add_double(h, "NTS-Search-Radius", sm->search_radius);
    add_double(h, "NTS-Cell-Size", sm->cell_size);
    add_int(h, "NTS-Stiffness-Triplets", r->triplets);
    add_int(h, "NTS-Deep-Contacts", sm->deep_contacts);
    if (r->friction) { /* friction's (docs/model.md §14), only when it is on */
        add_double(h, "NTS-Dissipation", sm->dissipation);
        add_int(h, "NTS-Sticking", sm->sticking);
        add_int(h, "NTS-Slipping", sm->slipping);
    }
    if (r->warning_count > 0) { /* what the result may lack: "code=count, ..." */
        v = add(h, "NTS-Warnings");
        for (w = 0, k = 0; w < r->warning_count && k < sizeof h->values[0]; ++w)
            k += (size_t)snprintf(v + k, sizeof h->values[0] - k, "%s%s=%lld", w > 0 ? ", " : "",
                                  nts_warning_name(r->warnings[w].code), r->warnings[w].count);
    }
}
