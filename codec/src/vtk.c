/* A result as a VTK XML unstructured grid (.vtu, ASCII), for ParaView and any
 * reader of VTK files (meshio reads it back in the tests).
 *
 *   points   every node of the scene (global order, z = 0), then the closest
 *            point (PCA) of every active contact;
 *   cells    every surface segment (a VTK_LINE between consecutive loop nodes,
 *            interior on the left), then every active contact (a VTK_LINE from
 *            the slave node to its PCA);
 *   point data  force (the contact force on each node; 0 on PCA points),
 *               pressure (the node's contact pressure, docs/model.md (21),
 *               when outputs has pressure, else 0; 0 on PCA points),
 *               body (body index; a PCA point has its master body);
 *   cell data   kind (0 segment, 1 contact), body (the segment's body, the
 *               contact's slave body), surface (1 for a segment on its
 *               body's contact surface, docs/model.md §13, 0 off it, -1 for
 *               contacts), master_body (-1 for segments),
 *               gap (0 for segments), normal (outward unit normal of the
 *               segment, or of the master at the PCA), contact_kind (-1,
 *               or 0 segment, 1 corner, 2 vertex), contact_force (force on
 *               the slave, 0 for segments); with friction on (docs/model.md
 *               §14) also tangential_force (its tangential part) and
 *               friction_state (-1 segments, 0 frictionless, 1 stick, 2 slip);
 *   field data  energy, virial (xx, yy, xy), contacts, max_penetration; with
 *               friction on, virial has yx too, and dissipation.
 *
 * Doubles are printed in their shortest round-trip form, so the file holds the
 * result exactly. Positions are as given: in a periodic box, a segment that
 * crosses the box's edge is drawn across the box (its normal is right). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "codec_internal.h"

static void put_double(ntsj_buf* b, double v) {
    char num[40];
    int n = ntsj_format_double(num, v);
    ntsj_buf_put(b, num, (size_t)n);
}

static void open_array(ntsj_buf* b, const char* type, const char* name, int components) {
    ntsj_buf_puts(b, "<DataArray type=\"");
    ntsj_buf_puts(b, type);
    ntsj_buf_puts(b, "\" Name=\"");
    ntsj_buf_puts(b, name);
    ntsj_buf_puts(b, "\" NumberOfComponents=\"");
    ntsj_buf_int(b, components);
    ntsj_buf_puts(b, "\" format=\"ascii\">\n");
}

static void close_array(ntsj_buf* b) { ntsj_buf_puts(b, "\n</DataArray>\n"); }

static void put_vec3(ntsj_buf* b, nts_vec2 v) {
    put_double(b, v.x);
    ntsj_buf_putc(b, ' ');
    put_double(b, v.y);
    ntsj_buf_puts(b, " 0\n");
}

static void field_double(ntsj_buf* b, const char* name, const double* v, int n) {
    int i;
    ntsj_buf_puts(b, "<DataArray type=\"Float64\" Name=\"");
    ntsj_buf_puts(b, name);
    ntsj_buf_puts(b, "\" NumberOfTuples=\"1\" NumberOfComponents=\"");
    ntsj_buf_int(b, n);
    ntsj_buf_puts(b, "\" format=\"ascii\">");
    for (i = 0; i < n; ++i) {
        if (i) ntsj_buf_putc(b, ' ');
        put_double(b, v[i]);
    }
    ntsj_buf_puts(b, "</DataArray>\n");
}

void ntsj_encode_vtk(ntsj_buf* b, const ntsj_scene* s, const nts_scene* scene, const nts_result* r) {
    double lx = s->has_periodic ? s->lx : 0.0, ly = s->has_periodic ? s->ly : 0.0;
    const nts_vec2* pos = nts_scene_positions(scene);
    int n = nts_scene_node_count(scene), segs = nts_scene_surface_node_count(scene);
    int nb = nts_scene_body_count(scene), nc = r->contacts ? r->contact_count : 0;
    const int friction = nts_friction_on(scene, &s->options);
    int body, l, k, i;
    ntsj_buf_hint(b, (size_t)(n + nc) * 120u + (size_t)(segs + nc) * 160u + 4096u);
    ntsj_buf_puts(b, "<?xml version=\"1.0\"?>\n"
                     "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
                     "<UnstructuredGrid>\n<FieldData>\n");
    {
        double energy = r->summary.energy, pen = r->summary.max_penetration, contacts = r->summary.contacts;
        double vir[4] = {r->summary.virial.xx, r->summary.virial.yy, r->summary.virial.xy, r->summary.virial.yx};
        double dissipation = r->summary.dissipation;
        field_double(b, "energy", &energy, 1);
        field_double(b, "virial", vir, friction ? 4 : 3);
        field_double(b, "contacts", &contacts, 1);
        field_double(b, "max_penetration", &pen, 1);
        if (friction) field_double(b, "dissipation", &dissipation, 1);
    }
    ntsj_buf_puts(b, "</FieldData>\n<Piece NumberOfPoints=\"");
    ntsj_buf_int(b, (long long)n + nc);
    ntsj_buf_puts(b, "\" NumberOfCells=\"");
    ntsj_buf_int(b, (long long)segs + nc);
    ntsj_buf_puts(b, "\">\n<Points>\n");
    open_array(b, "Float64", "Points", 3);
    for (i = 0; i < n; ++i) put_vec3(b, pos[i]);
    for (i = 0; i < nc; ++i) put_vec3(b, r->contacts[i].point);
    close_array(b);
    ntsj_buf_puts(b, "</Points>\n<Cells>\n");
    open_array(b, "Int64", "connectivity", 1);
    for (body = 0; body < nb; ++body) {
        int off = nts_scene_body_node_offset(scene, body);
        for (l = 0; l < nts_scene_body_loop_count(scene, body); ++l) {
            const int* loop;
            int m = nts_scene_body_loop(scene, body, l, &loop);
            for (k = 0; k < m; ++k) {
                ntsj_buf_int(b, off + loop[k]);
                ntsj_buf_putc(b, ' ');
                ntsj_buf_int(b, off + loop[(k + 1) % m]);
                ntsj_buf_putc(b, '\n');
            }
        }
    }
    for (i = 0; i < nc; ++i) {
        ntsj_buf_int(b, nts_scene_body_node_offset(scene, r->contacts[i].slave_body) + r->contacts[i].slave_node);
        ntsj_buf_putc(b, ' ');
        ntsj_buf_int(b, (long long)n + i);
        ntsj_buf_putc(b, '\n');
    }
    close_array(b);
    open_array(b, "Int64", "offsets", 1);
    for (i = 1; i <= segs + nc; ++i) {
        ntsj_buf_int(b, 2LL * i);
        ntsj_buf_putc(b, i % 16 ? ' ' : '\n');
    }
    close_array(b);
    open_array(b, "UInt8", "types", 1);
    for (i = 1; i <= segs + nc; ++i) ntsj_buf_puts(b, i % 32 ? "3 " : "3\n"); /* VTK_LINE */
    close_array(b);
    ntsj_buf_puts(b, "</Cells>\n<PointData Vectors=\"force\">\n");
    open_array(b, "Float64", "force", 3);
    for (i = 0; i < n; ++i) put_vec3(b, r->forces ? r->forces[i] : nts_v2(0.0, 0.0));
    for (i = 0; i < nc; ++i) ntsj_buf_puts(b, "0 0 0\n");
    close_array(b);
    open_array(b, "Float64", "pressure", 1);
    for (i = 0; i < n; ++i) {
        put_double(b, r->pressure ? r->pressure[i] : 0.0);
        ntsj_buf_putc(b, '\n');
    }
    for (i = 0; i < nc; ++i) ntsj_buf_puts(b, "0\n");
    close_array(b);
    open_array(b, "Int32", "body", 1);
    for (body = 0; body < nb; ++body) {
        int m = nts_scene_body_node_count(scene, body);
        for (k = 0; k < m; ++k) {
            ntsj_buf_int(b, body);
            ntsj_buf_putc(b, '\n');
        }
    }
    for (i = 0; i < nc; ++i) {
        ntsj_buf_int(b, r->contacts[i].master_body);
        ntsj_buf_putc(b, '\n');
    }
    close_array(b);
    ntsj_buf_puts(b, "</PointData>\n<CellData Normals=\"normal\">\n");
    /* Per cell, in the order of the connectivity: segments then contacts. */
    open_array(b, "Int32", "kind", 1);
    for (i = 0; i < segs + nc; ++i) ntsj_buf_puts(b, i < segs ? "0\n" : "1\n");
    close_array(b);
    open_array(b, "Int32", "body", 1);
    for (body = 0; body < nb; ++body) {
        for (l = 0; l < nts_scene_body_loop_count(scene, body); ++l) {
            int m = nts_scene_body_loop(scene, body, l, NULL);
            for (k = 0; k < m; ++k) {
                ntsj_buf_int(b, body);
                ntsj_buf_putc(b, '\n');
            }
        }
    }
    for (i = 0; i < nc; ++i) {
        ntsj_buf_int(b, r->contacts[i].slave_body);
        ntsj_buf_putc(b, '\n');
    }
    close_array(b);
    open_array(b, "Int32", "surface", 1);
    for (body = 0; body < nb; ++body) {
        for (l = 0; l < nts_scene_body_loop_count(scene, body); ++l) {
            int m = nts_scene_body_loop(scene, body, l, NULL);
            for (k = 0; k < m; ++k) ntsj_buf_puts(b, nts_scene_on_surface(scene, body, l, k) ? "1\n" : "0\n");
        }
    }
    for (i = 0; i < nc; ++i) ntsj_buf_puts(b, "-1\n");
    close_array(b);
    open_array(b, "Int32", "master_body", 1);
    for (i = 0; i < segs; ++i) ntsj_buf_puts(b, "-1\n");
    for (i = 0; i < nc; ++i) {
        ntsj_buf_int(b, r->contacts[i].master_body);
        ntsj_buf_putc(b, '\n');
    }
    close_array(b);
    open_array(b, "Float64", "gap", 1);
    for (i = 0; i < segs; ++i) ntsj_buf_puts(b, "0\n");
    for (i = 0; i < nc; ++i) {
        put_double(b, r->contacts[i].gap);
        ntsj_buf_putc(b, '\n');
    }
    close_array(b);
    open_array(b, "Float64", "normal", 3);
    for (body = 0; body < nb; ++body) {
        int off = nts_scene_body_node_offset(scene, body);
        for (l = 0; l < nts_scene_body_loop_count(scene, body); ++l) {
            const int* loop;
            int m = nts_scene_body_loop(scene, body, l, &loop);
            for (k = 0; k < m; ++k) {
                /* Outward: the interior is on the left of a normalised loop
                 * (docs/model.md §2). The minimum image keeps a
                 * segment across a periodic boundary short. */
                nts_vec2 p = pos[off + loop[k]], q = pos[off + loop[(k + 1) % m]];
                nts_vec2 t = nts_sub(q, p);
                double len;
                nts_vec2 nrm = nts_v2(0.0, 0.0);
                t = nts_min_image(t, lx, ly);
                len = nts_length(t);
                if (len > 0.0) nrm = nts_v2(t.y / len, -t.x / len);
                put_vec3(b, nrm);
            }
        }
    }
    for (i = 0; i < nc; ++i) put_vec3(b, r->contacts[i].normal);
    close_array(b);
    open_array(b, "Int32", "contact_kind", 1);
    for (i = 0; i < segs; ++i) ntsj_buf_puts(b, "-1\n");
    for (i = 0; i < nc; ++i) {
        ntsj_buf_int(b, (long long)r->contacts[i].kind);
        ntsj_buf_putc(b, '\n');
    }
    close_array(b);
    open_array(b, "Float64", "contact_force", 3);
    for (i = 0; i < segs; ++i) ntsj_buf_puts(b, "0 0 0\n");
    for (i = 0; i < nc; ++i) put_vec3(b, r->contacts[i].force);
    close_array(b);
    if (friction) {
        open_array(b, "Float64", "tangential_force", 3);
        for (i = 0; i < segs; ++i) ntsj_buf_puts(b, "0 0 0\n");
        for (i = 0; i < nc; ++i) put_vec3(b, r->contacts[i].tangential_force);
        close_array(b);
        open_array(b, "Int32", "friction_state", 1);
        for (i = 0; i < segs; ++i) ntsj_buf_puts(b, "-1\n");
        for (i = 0; i < nc; ++i) {
            ntsj_buf_int(b, (long long)r->contacts[i].state);
            ntsj_buf_putc(b, '\n');
        }
        close_array(b);
    }
    ntsj_buf_puts(b, "</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
}
