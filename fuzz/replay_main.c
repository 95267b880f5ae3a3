/* Plain replay driver (issue 7): links the libFuzzer entry point of
 * fuzz_handle.c with a main() that feeds it every file named on the command
 * line, or every file of every directory named, in name order. Built with any
 * compiler; under -DNTS_SANITIZE=ON (gcc's ASan + UBSan, no recover) it replays
 * the seed corpus and the regression inputs inside the test suite. A crash,
 * a sanitizer report or a contract breach aborts with the file name printed. */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

static int replay_file(const char* path) {
    FILE* f = fopen(path, "rb");
    uint8_t* buf;
    long n;
    size_t got;
    if (f == NULL) {
        fprintf(stderr, "replay: cannot open %s\n", path);
        return -1;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        fprintf(stderr, "replay: cannot size %s\n", path);
        return -1;
    }
    /* An exact-size copy, so ASan sees any read past the input's end. */
    buf = (uint8_t*)malloc(n > 0 ? (size_t)n : 1);
    if (buf == NULL) {
        fclose(f);
        return -1;
    }
    got = fread(buf, 1, (size_t)n, f);
    fclose(f);
    if (got != (size_t)n) {
        free(buf);
        fprintf(stderr, "replay: short read on %s\n", path);
        return -1;
    }
    fprintf(stderr, "replay: %s (%ld bytes)\n", path, n);
    LLVMFuzzerTestOneInput(buf, (size_t)n);
    free(buf);
    return 0;
}

static int by_name(const void* a, const void* b) { return strcmp(*(char* const*)a, *(char* const*)b); }

static int replay_dir(const char* dir, int* count) {
    DIR* d = opendir(dir);
    struct dirent* e;
    char** names = NULL;
    size_t n = 0, cap = 0, i;
    int rc = 0;
    if (d == NULL) {
        fprintf(stderr, "replay: cannot open directory %s\n", dir);
        return -1;
    }
    while ((e = readdir(d)) != NULL) {
        size_t len;
        char* path;
        struct stat st;
        if (e->d_name[0] == '.') continue;
        len = strlen(dir) + strlen(e->d_name) + 2;
        path = (char*)malloc(len);
        if (path == NULL) { rc = -1; break; }
        snprintf(path, len, "%s/%s", dir, e->d_name);
        if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
            free(path);
            continue;
        }
        if (n == cap) {
            char** grown = (char**)realloc(names, (cap = cap ? 2 * cap : 64) * sizeof *names);
            if (grown == NULL) { free(path); rc = -1; break; }
            names = grown;
        }
        names[n++] = path;
    }
    closedir(d);
    if (n > 0) qsort(names, n, sizeof *names, by_name);
    for (i = 0; i < n; ++i) {
        if (rc == 0 && replay_file(names[i]) != 0) rc = -1;
        else if (rc == 0) ++*count;
        free(names[i]);
    }
    free(names);
    return rc;
}

int main(int argc, char** argv) {
    int i, count = 0, rc = 0;
    if (argc < 2) {
        fprintf(stderr, "usage: %s FILE|DIR...\n", argv[0]);
        return 2;
    }
    for (i = 1; i < argc && rc == 0; ++i) {
        struct stat st;
        if (stat(argv[i], &st) != 0) {
            fprintf(stderr, "replay: no such file or directory: %s\n", argv[i]);
            rc = -1;
        } else if (S_ISDIR(st.st_mode)) {
            rc = replay_dir(argv[i], &count);
        } else {
            rc = replay_file(argv[i]);
            if (rc == 0) ++count;
        }
    }
    printf("replayed %d inputs%s\n", count, rc == 0 ? "" : " (stopped on an error)");
    return rc == 0 && count > 0 ? 0 : 1;
}
