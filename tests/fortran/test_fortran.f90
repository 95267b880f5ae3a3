! The Fortran module (fortran/ntscontact.f90) against the C API, on a bundled
! example scene given as the argument (tests/CMakeLists.txt runs it on three).
!
! reference.c reads the scene with cJSON into arrays and evaluates it through
! the C API directly; this program builds the same scene from those arrays
! through the module (1-based indices) and checks, bit for bit:
! - forces, energy, virial and contact count against the C reference;
! - the tangent in CSR against the C triplets, summed here on their own in
!   triplet order, with rows and columns shifted to 1-based and each row's
!   columns increasing;
! - positions moved through ntsf_update_positions (a session's step), then
!   evaluated, against a fresh C scene created at those positions;
! - a step that gives only the loops' nodes (surface_only, ntsf_surface_nodes),
!   the other entries not a number, against a fresh C scene;
! - a solver's loop with a kept candidate list (ntsf_candidates): every step
!   against a fresh C scene at its positions, the list built and replayed;
! - a sequence of steps with friction and a history (ntsf_history) against
!   the same sequence through the C API, and the history's effect;
! and the error paths: a zero-length segment, a node index out of range, a
! coordinate that is not a number (the scene then unchanged), positions of
! the wrong shape, an invalid option, a destroyed handle. Also the module's
! constants against the C tables and its types' sizes against the C structs.
program test_fortran
  use, intrinsic :: iso_c_binding
  use, intrinsic :: iso_fortran_env, only: error_unit, int64
  use ntscontact
  implicit none

  interface
    function ftest_load(path) bind(c, name="ftest_load")
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: ftest_load
    end function ftest_load
    function ftest_body_count() bind(c, name="ftest_body_count")
      import :: c_int
      integer(c_int) :: ftest_body_count
    end function ftest_body_count
    subroutine ftest_body_sizes(b, nodes, triangles, loops, loop_length) bind(c, name="ftest_body_sizes")
      import :: c_int
      integer(c_int), value :: b
      integer(c_int), intent(out) :: nodes, triangles, loops, loop_length
    end subroutine ftest_body_sizes
    subroutine ftest_body_arrays(b, xy, triangles, loop_nodes, loop_start) bind(c, name="ftest_body_arrays")
      import :: c_int, c_double
      integer(c_int), value :: b
      real(c_double), intent(out) :: xy(*)
      integer(c_int), intent(out) :: triangles(*), loop_nodes(*), loop_start(*)
    end subroutine ftest_body_arrays
    subroutine ftest_scene_options(alpha, penalty, search_radius, lx, ly) bind(c, name="ftest_scene_options")
      import :: c_double
      real(c_double), intent(out) :: alpha, penalty, search_radius, lx, ly
    end subroutine ftest_scene_options
    function ftest_reference(positions) bind(c, name="ftest_reference")
      import :: c_int, c_double
      real(c_double), intent(in) :: positions(*)
      integer(c_int) :: ftest_reference
    end function ftest_reference
    subroutine ftest_reference_summary(energy, virial, contacts, max_penetration) bind(c, name="ftest_reference_summary")
      import :: c_int, c_double
      real(c_double), intent(out) :: energy, virial(4), max_penetration
      integer(c_int), intent(out) :: contacts
    end subroutine ftest_reference_summary
    subroutine ftest_reference_forces(xy) bind(c, name="ftest_reference_forces")
      import :: c_double
      real(c_double), intent(out) :: xy(*)
    end subroutine ftest_reference_forces
    function ftest_reference_triplet_count() bind(c, name="ftest_reference_triplet_count")
      import :: c_int
      integer(c_int) :: ftest_reference_triplet_count
    end function ftest_reference_triplet_count
    subroutine ftest_reference_triplets(rows, cols, values) bind(c, name="ftest_reference_triplets")
      import :: c_int, c_double
      integer(c_int), intent(out) :: rows(*), cols(*)
      real(c_double), intent(out) :: values(*)
    end subroutine ftest_reference_triplets
    function ftest_status_table(values, max) bind(c, name="ftest_status_table")
      import :: c_int
      integer(c_int), intent(out) :: values(*)
      integer(c_int), value :: max
      integer(c_int) :: ftest_status_table
    end function ftest_status_table
    function ftest_output_table(bits, max) bind(c, name="ftest_output_table")
      import :: c_int
      integer(c_int), intent(out) :: bits(*)
      integer(c_int), value :: max
      integer(c_int) :: ftest_output_table
    end function ftest_output_table
    function ftest_warning_table(values, max) bind(c, name="ftest_warning_table")
      import :: c_int
      integer(c_int), intent(out) :: values(*)
      integer(c_int), value :: max
      integer(c_int) :: ftest_warning_table
    end function ftest_warning_table
    function ftest_friction_step(positions, friction, commit) bind(c, name="ftest_friction_step")
      import :: c_int, c_double
      real(c_double), intent(in) :: positions(*)
      real(c_double), value :: friction
      integer(c_int), value :: commit
      integer(c_int) :: ftest_friction_step
    end function ftest_friction_step
    subroutine ftest_friction_out(xy, sums, counts) bind(c, name="ftest_friction_out")
      import :: c_int, c_double
      real(c_double), intent(out) :: xy(*), sums(6)
      integer(c_int), intent(out) :: counts(4)
    end subroutine ftest_friction_out
    function ftest_reference_record_count(gaps) bind(c, name="ftest_reference_record_count")
      import :: c_int
      integer(c_int), value :: gaps
      integer(c_int) :: ftest_reference_record_count
    end function ftest_reference_record_count
    subroutine ftest_reference_record(gaps, k, ints, reals) bind(c, name="ftest_reference_record")
      import :: c_int, c_double
      integer(c_int), value :: gaps, k
      integer(c_int), intent(out) :: ints(9)
      real(c_double), intent(out) :: reals(19)
    end subroutine ftest_reference_record
    subroutine ftest_kind_state_values(values) bind(c, name="ftest_kind_state_values")
      import :: c_int
      integer(c_int), intent(out) :: values(6)
    end subroutine ftest_kind_state_values
    function ftest_surface_node_count() bind(c, name="ftest_surface_node_count")
      import :: c_int
      integer(c_int) :: ftest_surface_node_count
    end function ftest_surface_node_count
    subroutine ftest_free() bind(c, name="ftest_free")
    end subroutine ftest_free
  end interface

  integer :: failures = 0
  type(ntsf_body), allocatable :: bodies(:)
  type(ntsf_scene) :: scene
  type(ntsf_output) :: out, moved_out, again
  type(nts_options) :: opt
  type(nts_error) :: err
  real(c_double) :: alpha, penalty, radius, lx, ly
  real(c_double), allocatable :: x0(:, :), x1(:, :), bad(:, :)
  character(len=4096) :: path
  character(len=:), allocatable :: detail
  integer :: status, n, i

  if (command_argument_count() /= 1) then
    write (error_unit, fmt('(a)')) "usage: test_fortran SCENE.json"
    error stop 2
  end if
  call get_command_argument(1, path)

  call check(ntsf_layout_ok(detail), "the module's bind(C) types have the C structs' sizes: "//detail)
  call check_tables()

  if (ftest_load(trim(path)//c_null_char) /= 0) then
    write (error_unit, fmt('(2a)')) "cannot read ", trim(path)
    error stop 2
  end if
  call read_bodies(bodies)
  call ftest_scene_options(alpha, penalty, radius, lx, ly) ! for the box: options_of_file sets the options
  opt = options_of_file()

  ! The scene through the module, evaluated, against the C API's own.
  call ntsf_scene_create(scene, bodies, status, lx=lx, ly=ly, err=err)
  call check(status == NTS_OK, "ntsf_scene_create: "//ntsf_status_name(status)//": "//ntsf_error_message(err))
  if (status /= NTS_OK) call finish()
  n = ntsf_node_count(scene)
  call check(n == sum([(size(bodies(i)%nodes, 2), i = 1, size(bodies))]), "ntsf_node_count is every body's nodes")
  call check(ntsf_body_count(scene) == size(bodies), "ntsf_body_count")
  x0 = all_nodes(bodies, n)

  call ntsf_evaluate(scene, opt, out, status, err)
  call check(status == NTS_OK, "ntsf_evaluate: "//ntsf_error_message(err))
  call check(ftest_reference(x0) == NTS_OK, "the C reference evaluates")
  call compare(out, n, "at the file's positions")
  call check(out%summary%contacts > 0, "the example has active contacts (else the comparison says little)")
  call check(out%tangent%n == 2 * n .and. size(out%tangent%val) > 0, "the tangent is 2N x 2N and not empty")

  ! A session's step: the same scene at moved positions, against a fresh C
  ! scene created there.
  x1 = x0
  do i = 1, n
    x1(1, i) = x0(1, i) + 1.0e-3_c_double * sin(real(i, c_double))
    x1(2, i) = x0(2, i) + 1.0e-3_c_double * cos(real(i, c_double))
  end do
  call ntsf_update_positions(scene, x1, status, err)
  call check(status == NTS_OK, "ntsf_update_positions: "//ntsf_error_message(err))
  call ntsf_evaluate(scene, opt, moved_out, status, err)
  call check(status == NTS_OK, "ntsf_evaluate after the update: "//ntsf_error_message(err))
  call check(ftest_reference(x1) == NTS_OK, "the C reference evaluates at the moved positions")
  call compare(moved_out, n, "at the moved positions")
  call check(.not. same_bits([moved_out%summary%energy], [out%summary%energy]), &
    "the moved positions give another energy (the update took)")

  ! The step in one call (positions=): the same bits as the update then the
  ! evaluation, back at x0 and again at x1; refused positions change nothing.
  call ntsf_evaluate(scene, opt, again, status, err, positions=x0)
  call check(status == NTS_OK, "ntsf_evaluate(positions=x0): "//ntsf_error_message(err))
  call check(ftest_reference(x0) == NTS_OK, "the C reference evaluates at the first positions")
  call compare(again, n, "back at the first positions, in one call")
  call check(ftest_reference(x1) == NTS_OK, "the C reference evaluates at the moved positions")
  call ntsf_evaluate(scene, opt, again, status, err, positions=x1)
  call check(status == NTS_OK .and. same_bits(flat(again%forces), flat(moved_out%forces)) .and. &
    same_bits([again%summary%energy], [moved_out%summary%energy]), "the moved positions in one call: the same bits")
  bad = x1
  bad(1, n) = ieee_nan()
  call ntsf_evaluate(scene, opt, again, status, err, positions=bad)
  call check(status == NTS_ENONFINITE .and. err%code == NTS_ENONFINITE .and. .not. allocated(again%forces), &
    "a NaN coordinate in one call: NTS_ENONFINITE, nothing out")
  call ntsf_evaluate(scene, opt, again, status, err, positions=x1(:, 1:n - 1))
  call check(status == NTS_EINVALID_ARGUMENT, "positions of the wrong shape in one call: NTS_EINVALID_ARGUMENT")
  call ntsf_evaluate(scene, opt, again, status)
  call check(status == NTS_OK .and. same_bits(flat(again%forces), flat(moved_out%forces)), &
    "the refused positions in one call changed nothing")

  ! Errors: a coordinate that is not a number leaves the scene as it was.
  bad = x1
  bad(2, n) = ieee_nan()
  call ntsf_update_positions(scene, bad, status, err)
  call check(status == NTS_ENONFINITE .and. err%code == NTS_ENONFINITE, "a NaN coordinate is NTS_ENONFINITE")
  call check(len(ntsf_error_message(err)) > 0, "and its message says where")
  call ntsf_evaluate(scene, opt, again, status)
  call check(status == NTS_OK .and. same_bits(flat(again%forces), flat(moved_out%forces)) .and. &
    same_bits([again%summary%energy], [moved_out%summary%energy]), "the refused positions changed nothing")
  call ntsf_update_positions(scene, x1(:, 1:n - 1), status, err)
  call check(status == NTS_EINVALID_ARGUMENT, "positions of the wrong shape are NTS_EINVALID_ARGUMENT")

  opt%penalty = -1
  call ntsf_evaluate(scene, opt, again, status, err)
  call check(status == NTS_EINVALID_OPTION .and. c_text(err%option) == "penalty", &
    "a negative penalty is NTS_EINVALID_OPTION naming penalty")
  call check(.not. allocated(again%forces) .and. again%summary%contacts == 0, "a failed evaluation gives nothing")
  opt = options_of_file()

  call check_surface(bodies, x0, x1, n, lx, ly)
  call check_kept(bodies, x0, n, lx, ly, out%summary%search_radius)
  call check_friction(bodies, x0, n, lx, ly, out%summary%search_radius)

  call ntsf_scene_destroy(scene)
  call ntsf_scene_destroy(scene) ! twice: nothing
  call ntsf_evaluate(scene, opt, again, status)
  call check(status == NTS_EINVALID_ARGUMENT .and. ntsf_node_count(scene) == 0, "a destroyed handle evaluates nothing")
  call check_scene_errors(bodies)

  if (failures == 0) write (*, fmt('(a, i0, a, i0, a, i0, a, es22.16, a)')) "fortran: ", n, " nodes, ", &
    out%summary%contacts, " contacts, tangent nnz ", size(out%tangent%val), ", energy ", out%summary%energy, &
    ", forces, energy, virial and tangent equal to the C API bitwise, before and after an update of positions, "// &
    "over a kept candidate list's steps and a friction sequence's"
  call finish()

contains

  subroutine check(ok, what)
    logical, intent(in) :: ok
    character(len=*), intent(in) :: what
    if (.not. ok) then
      failures = failures + 1
      write (error_unit, fmt('(2a)')) "FAIL: ", what
    end if
  end subroutine check

  subroutine finish()
    call ntsf_scene_destroy(scene)
    call ftest_free()
    if (failures > 0) then
      write (error_unit, fmt('(a, i0, a)')) "test_fortran: ", failures, " failed"
      error stop 1
    end if
    stop
  end subroutine finish

  ! A format with a NUL after it: libgfortran copies a format with strndup,
  ! which AddressSanitizer's strict_string_checks (scripts/test-sanitize.sh)
  ! reads to a NUL, past the end of a Fortran string without one. The
  ! characters after a format's closing parenthesis have no effect.
  pure function fmt(spec) result(f)
    character(len=*), intent(in) :: spec
    character(len=len(spec) + 1) :: f
    f = spec//c_null_char
  end function fmt

  ! Bitwise, so that -0.0 and 0.0 (or two NaNs) are told apart as C's bits are.
  logical function same_bits(a, b)
    real(c_double), intent(in) :: a(:), b(:)
    same_bits = size(a) == size(b)
    if (same_bits) same_bits = all(transfer(a, [0_int64]) == transfer(b, [0_int64]))
  end function same_bits

  function flat(x) result(v)
    real(c_double), intent(in) :: x(:, :)
    real(c_double) :: v(size(x))
    v = reshape(x, [size(x)])
  end function flat

  function options_of_file() result(o)
    type(nts_options) :: o
    real(c_double) :: bx, by
    o = nts_default_options()
    call ftest_scene_options(o%alpha, o%penalty, o%search_radius, bx, by)
    o%outputs = ior(ior(ior(NTS_OUT_FORCES, NTS_OUT_ENERGY), ior(NTS_OUT_VIRIAL, NTS_OUT_STIFFNESS)), &
      ior(NTS_OUT_CONTACTS, NTS_OUT_GAPS))
  end function options_of_file

  ! The file's bodies as the module takes them: node indices 1-based.
  subroutine read_bodies(b)
    type(ntsf_body), allocatable, intent(out) :: b(:)
    integer(c_int) :: nodes, tri, loops, loop_length
    integer :: k
    allocate (b(ftest_body_count()))
    do k = 1, size(b)
      call ftest_body_sizes(int(k - 1, c_int), nodes, tri, loops, loop_length)
      allocate (b(k)%nodes(2, nodes), b(k)%triangles(3, tri), b(k)%loop_nodes(loop_length))
      allocate (b(k)%loop_start(loops + 1))
      call ftest_body_arrays(int(k - 1, c_int), b(k)%nodes, b(k)%triangles, b(k)%loop_nodes, b(k)%loop_start)
      b(k)%triangles = b(k)%triangles + 1
      b(k)%loop_nodes = b(k)%loop_nodes + 1
      b(k)%loop_start = b(k)%loop_start + 1
      if (tri == 0) deallocate (b(k)%triangles)
      if (loops == 0) deallocate (b(k)%loop_nodes, b(k)%loop_start)
    end do
  end subroutine read_bodies

  function all_nodes(b, count) result(x)
    type(ntsf_body), intent(in) :: b(:)
    integer, intent(in) :: count
    real(c_double) :: x(2, count)
    integer :: k, at
    at = 0
    do k = 1, size(b)
      x(:, at + 1:at + size(b(k)%nodes, 2)) = b(k)%nodes
      at = at + size(b(k)%nodes, 2)
    end do
  end function all_nodes

  ! x0 moved: node i by amplitude a along a direction of its own.
  function moved(x0, a) result(x)
    real(c_double), intent(in) :: x0(:, :), a
    real(c_double) :: x(size(x0, 1), size(x0, 2))
    integer :: i
    do i = 1, size(x0, 2)
      x(1, i) = x0(1, i) + a * sin(1.7_c_double * i)
      x(2, i) = x0(2, i) + a * cos(1.3_c_double * i)
    end do
  end function moved

  ! A step that gives the loops' nodes alone (surface_only): the other
  ! entries of the positions not a number, the answer that of a fresh C
  ! scene at the stored positions with the loops' nodes moved, and the scene
  ! then at those positions; ntsf_surface_nodes lists every node of the
  ! loops once (else a NaN would reach one the evaluation reads).
  subroutine check_surface(b, x0, x1, nodes, box_x, box_y)
    type(ntsf_body), intent(in) :: b(:)
    real(c_double), intent(in) :: x0(:, :), x1(:, :), box_x, box_y
    integer, intent(in) :: nodes
    type(ntsf_scene) :: ss, none
    type(ntsf_output) :: so, again
    type(nts_options) :: o
    type(nts_error) :: e
    integer(c_int), allocatable :: surf(:)
    logical :: on(nodes)
    real(c_double) :: xr(2, nodes), xj(2, nodes)
    integer :: st, k

    o = options_of_file()
    call ntsf_scene_create(ss, b, st, lx=box_x, ly=box_y, err=e)
    call check(st == NTS_OK, "surface: ntsf_scene_create: "//ntsf_error_message(e))
    call ntsf_surface_nodes(ss, surf)
    call check(ftest_reference(x0) == NTS_OK, "the C reference evaluates (surface)")
    call check(size(surf) == ftest_surface_node_count(), "ntsf_surface_nodes: as many as the C scene's loop nodes")
    call check(all(surf >= 1 .and. surf <= nodes), "ntsf_surface_nodes: 1-based global nodes")
    on = .false.
    do k = 1, size(surf)
      if (surf(k) >= 1 .and. surf(k) <= nodes) on(surf(k)) = .true.
    end do
    call check(count(on) == size(surf), "ntsf_surface_nodes: each node once")
    xr = x0
    xr(:, surf) = x1(:, surf)
    xj = x1
    do k = 1, nodes
      if (.not. on(k)) xj(:, k) = ieee_nan()
    end do
    call ntsf_evaluate(ss, o, so, st, e, positions=xj, surface_only=.true.)
    call check(st == NTS_OK, "a surface-only step: "//ntsf_error_message(e))
    call check(ftest_reference(xr) == NTS_OK, "the C reference evaluates at the surface step's positions")
    call compare(so, nodes, "after a surface-only step")
    call ntsf_evaluate(ss, o, again, st, e)
    call check(st == NTS_OK .and. same_bits(flat(again%forces), flat(so%forces)), &
      "the scene holds the surface step's positions")
    if (size(surf) < nodes) then
      call ntsf_evaluate(ss, o, again, st, e, positions=xj)
      call check(st == NTS_ENONFINITE, "the same positions for every node: the interior's NaN refused")
    end if
    call ntsf_evaluate(ss, o, again, st, e, surface_only=.true.)
    call check(st == NTS_EINVALID_ARGUMENT, "surface_only without positions: NTS_EINVALID_ARGUMENT")
    call ntsf_surface_nodes(none, surf)
    call check(size(surf) == 0, "an empty handle has no surface nodes")
    call ntsf_scene_destroy(ss)
  end subroutine check_surface

  ! A solver's loop with a kept candidate list: each step's answer against a
  ! fresh C scene at its positions (compare: forces, energy, virial, contact
  ! count, maximum penetration and tangent, bit for bit), while the list is
  ! built, replayed over steps well within its skin, built again after a
  ! jump past it and after a clear; and the handle's errors.
  subroutine check_kept(b, x0, count, box_x, box_y, radius)
    type(ntsf_body), intent(in) :: b(:)
    real(c_double), intent(in) :: x0(:, :), box_x, box_y, radius
    integer, intent(in) :: count
    ! the steps' amplitudes, in search radii: 0.4% more each step (the
    ! skin, 0.3 radii, allows about 8% between builds), then a jump of 40%
    ! (built again), two steps from there (replayed), back to the start
    real(c_double), parameter :: amp(10) = [0.0_c_double, 0.004_c_double, 0.008_c_double, 0.012_c_double, &
      0.016_c_double, 0.02_c_double, 0.4_c_double, 0.404_c_double, 0.408_c_double, 0.0_c_double]
    type(ntsf_scene) :: ks
    type(ntsf_candidates) :: kc
    type(ntsf_output) :: ko
    type(nts_options) :: o
    type(nts_error) :: e
    type(nts_candidates_info) :: info
    real(c_double) :: x(2, count)
    integer :: st, k
    character(len=2) :: tag

    o = options_of_file()
    call ntsf_scene_create(ks, b, st, lx=box_x, ly=box_y, err=e)
    call check(st == NTS_OK, "kept: ntsf_scene_create: "//ntsf_error_message(e))
    call ntsf_evaluate(ks, o, ko, st, e, candidates=kc)
    call check(st == NTS_EINVALID_ARGUMENT .and. .not. allocated(ko%forces), &
      "an empty candidate list handle: NTS_EINVALID_ARGUMENT, nothing out")
    call ntsf_candidates_create(kc, st, skin=-1.0_c_double, err=e)
    call check(st == NTS_EINVALID_ARGUMENT .and. e%code == NTS_EINVALID_ARGUMENT, "a negative skin is refused")
    call ntsf_candidates_create(kc, st, skin=ieee_nan())
    call check(st == NTS_EINVALID_ARGUMENT, "a skin that is not a number is refused")
    call ntsf_candidates_create(kc, st)
    call check(st == NTS_OK, "ntsf_candidates_create")
    do k = 1, size(amp)
      write (tag, fmt('(i2)')) k
      x = moved(x0, amp(k) * radius)
      call ntsf_evaluate(ks, o, ko, st, e, positions=x, candidates=kc)
      call check(st == NTS_OK, "kept step "//tag//": "//ntsf_error_message(e))
      call check(ftest_reference(x) == NTS_OK, "the C reference evaluates at kept step "//tag)
      call compare(ko, count, "at kept step "//tag)
      if (k == 6 .or. k == 9) info = ntsf_candidates_info(kc)
      if (k == 6) call check(info%builds == 1 .and. info%evaluations == 6 .and. info%kept > 0, &
        "the list is built once and replayed over the small steps")
      if (k == 9) call check(info%builds == 2 .and. info%evaluations == 9, "the jump builds it again, once")
    end do
    info = ntsf_candidates_info(kc)
    call check(info%builds == 3, "back to the start: built again")
    call ntsf_candidates_clear(kc)
    call ntsf_evaluate(ks, o, ko, st, e, positions=x, candidates=kc)
    info = ntsf_candidates_info(kc)
    call check(st == NTS_OK .and. info%builds == 4, "after a clear the next evaluation builds it")
    call ntsf_candidates_destroy(kc)
    call ntsf_candidates_destroy(kc) ! twice: nothing
    info = ntsf_candidates_info(kc)
    call check(info%evaluations == 0 .and. info%builds == 0, "a destroyed list's counts are zero")
    call ntsf_evaluate(ks, o, ko, st, e, candidates=kc)
    call check(st == NTS_EINVALID_ARGUMENT, "a destroyed candidate list: NTS_EINVALID_ARGUMENT")
    call ntsf_scene_destroy(ks)
  end subroutine check_kept

  ! A sequence of steps with friction: the last body slides while the
  ! others stay, each step a trial from the history and then committed, as
  ! an explicit solver does; each step's forces, energy, dissipation,
  ! virial and stick/slip counts against the same sequence through the C
  ! API, bit for bit. The history must matter: from the second step on,
  ! the same positions evaluated without it give other forces.
  subroutine check_friction(b, x0, count, box_x, box_y, radius)
    type(ntsf_body), intent(in) :: b(:)
    real(c_double), intent(in) :: x0(:, :), box_x, box_y, radius
    integer, intent(in) :: count
    type(ntsf_scene) :: fs, copy
    type(ntsf_history) :: h
    type(ntsf_output) :: fo, fresh
    type(nts_options) :: o
    type(nts_error) :: e
    real(c_double) :: x(2, count), f(2, count), sums(6)
    integer(c_int) :: counts(4)
    integer :: st, k, first
    character(len=2) :: tag

    o = options_of_file()
    o%outputs = ior(ior(NTS_OUT_FORCES, NTS_OUT_ENERGY), ior(NTS_OUT_VIRIAL, NTS_OUT_CONTACTS))
    o%friction = 0.4_c_double
    first = count - size(b(size(b))%nodes, 2) + 1 ! the last body's first node
    call ntsf_scene_create(fs, b, st, lx=box_x, ly=box_y, err=e)
    call check(st == NTS_OK, "friction: ntsf_scene_create: "//ntsf_error_message(e))
    call ntsf_history_commit(h, fs, st, e)
    call check(st == NTS_EINVALID_ARGUMENT, "a commit to an empty history handle: NTS_EINVALID_ARGUMENT")
    call ntsf_history_create(h, st)
    call check(st == NTS_OK .and. ntsf_history_count(h) == 0, "ntsf_history_create: empty")
    call ntsf_history_commit(h, fs, st, e)
    call check(st == NTS_EINVALID_ARGUMENT .and. len(ntsf_error_message(e)) > 0, &
      "a commit before any evaluation: NTS_EINVALID_ARGUMENT")
    do k = 0, 3
      write (tag, fmt('(i2)')) k
      x = x0
      x(1, first:) = x0(1, first:) + 0.03_c_double * k * radius
      x(2, first:) = x0(2, first:) + 0.02_c_double * k * radius
      call ntsf_evaluate(fs, o, fo, st, e, positions=x, history=h)
      call check(st == NTS_OK, "friction step "//tag//": "//ntsf_error_message(e))
      call check(ftest_friction_step(x, o%friction, 1_c_int) == NTS_OK, "the C sequence's step "//tag)
      call ftest_friction_out(f, sums, counts)
      call check(allocated(fo%forces), "friction step "//tag//": forces")
      if (.not. allocated(fo%forces)) exit
      call check(same_bits(flat(fo%forces), flat(f)), "friction step "//tag//": forces equal C's")
      call check(same_bits([fo%summary%energy, fo%summary%dissipation, fo%summary%virial%xx, &
        fo%summary%virial%yy, fo%summary%virial%xy, fo%summary%virial%yx], sums), &
        "friction step "//tag//": energy, dissipation and virial equal C's")
      call check(fo%summary%contacts == counts(1) .and. fo%summary%sticking == counts(2) .and. &
        fo%summary%slipping == counts(3), "friction step "//tag//": contacts, sticking and slipping equal C's")
      call check(size(fo%contacts) == counts(1) .and. size(pack(fo%contacts, fo%contacts%state == NTS_STICK)) == &
        counts(2) .and. size(pack(fo%contacts, fo%contacts%state == NTS_SLIP)) == counts(3), &
        "friction step "//tag//": the contacts' states are the summary's")
      call ntsf_history_commit(h, fs, st, e)
      call check(st == NTS_OK .and. ntsf_history_count(h) == counts(4), &
        "friction step "//tag//": committed, the anchors C's")
      if (k >= 1) then
        call ntsf_evaluate(fs, o, fresh, st, e, positions=x)
        call check(st == NTS_OK .and. .not. same_bits(flat(fresh%forces), flat(fo%forces)), &
          "friction step "//tag//": without the history, other forces (the history took)")
      end if
    end do
    call check(counts(1) > 0 .and. ntsf_history_count(h) > 0, "the sequence has stuck contacts (else it says little)")
    call ntsf_history_clear(h)
    call check(ntsf_history_count(h) == 0, "a cleared history holds no anchor")
    o%penalty = -1
    call ntsf_evaluate(fs, o, fo, st, e, positions=x, history=h)
    call ntsf_history_commit(h, fs, st, e)
    call check(st == NTS_EINVALID_ARGUMENT, "a commit after a failed evaluation: NTS_EINVALID_ARGUMENT")
    ! A copy of the handle shares its context, and so its last evaluation:
    ! a commit through one copy keeps the last evaluation through any.
    o%penalty = -o%penalty
    call ntsf_evaluate(fs, o, fo, st, e, positions=x, history=h)
    call check(st == NTS_OK, "the sequence's scene evaluates again")
    copy = fs
    o%penalty = -1
    call ntsf_evaluate(copy, o, fresh, st, e, positions=x, history=h)
    call ntsf_history_commit(h, fs, st, e)
    call check(st == NTS_EINVALID_ARGUMENT, "a commit after a copy's failed evaluation: NTS_EINVALID_ARGUMENT")
    call ntsf_history_destroy(h)
    call ntsf_history_destroy(h) ! twice: nothing
    call check(ntsf_history_count(h) == 0, "a destroyed history holds no anchor")
    call ntsf_scene_destroy(fs)
  end subroutine check_friction

  ! The module's answer against the C reference's last evaluation.
  subroutine compare(o, count, where)
    type(ntsf_output), intent(in) :: o
    integer, intent(in) :: count
    character(len=*), intent(in) :: where
    real(c_double) :: energy, virial(4), max_pen, f(2, count)
    integer(c_int) :: contacts, nt
    integer(c_int), allocatable :: rows(:), cols(:)
    real(c_double), allocatable :: vals(:)

    call ftest_reference_summary(energy, virial, contacts, max_pen)
    call ftest_reference_forces(f)
    call check(same_bits([o%summary%energy], [energy]), "energy "//where)
    call check(same_bits([o%summary%virial%xx, o%summary%virial%yy, o%summary%virial%xy, o%summary%virial%yx], &
      virial), "virial "//where)
    call check(o%summary%contacts == contacts, "contact count "//where)
    call check(same_bits([o%summary%max_penetration], [max_pen]), "max penetration "//where)
    call check(allocated(o%forces), "forces allocated "//where)
    if (allocated(o%forces)) call check(same_bits(flat(o%forces), flat(f)), "forces "//where)
    nt = ftest_reference_triplet_count()
    allocate (rows(max(nt, 1)), cols(max(nt, 1)), vals(max(nt, 1)))
    call ftest_reference_triplets(rows, cols, vals)
    call check_csr(o%tangent, rows(1:nt), cols(1:nt), vals(1:nt), 2 * count, where)
    call check_records(o%contacts, 0, "contacts "//where)
    call check_records(o%gaps, 1, "gaps "//where)
  end subroutine compare

  ! The module's contacts or gaps against the C reference's records: the
  ! indices one more (C's -1 past a feature's nodes: 0), every real the same bits.
  subroutine check_records(rec, gaps, where)
    type(ntsf_contact), allocatable, intent(in) :: rec(:)
    integer, intent(in) :: gaps
    character(len=*), intent(in) :: where
    integer(c_int) :: ints(9), m
    real(c_double) :: reals(19)
    integer :: k, bad
    m = ftest_reference_record_count(int(gaps, c_int))
    call check(allocated(rec), where//": allocated")
    if (.not. allocated(rec)) return
    call check(size(rec) == m, where//": as many as C's")
    if (size(rec) /= m) return
    bad = 0
    do k = 1, m
      call ftest_reference_record(int(gaps, c_int), int(k - 1, c_int), ints, reals)
      if (.not. (rec(k)%slave_body == ints(1) + 1 .and. rec(k)%slave_node == ints(2) + 1 .and. &
          rec(k)%master_body == ints(3) + 1 .and. rec(k)%kind == ints(4) .and. rec(k)%master_count == ints(5) .and. &
          all(rec(k)%master_nodes == ints(6:8) + 1) .and. rec(k)%state == ints(9) .and. &
          same_bits([rec(k)%weights, rec(k)%param, rec(k)%gap, rec(k)%normal, rec(k)%point, rec(k)%force, &
          rec(k)%virial, rec(k)%penalty, rec(k)%tangential_force, rec(k)%slip], reals))) bad = bad + 1
    end do
    call check(bad == 0, where//": every record C's")
  end subroutine check_records

  ! The CSR against the triplets: rows and columns 1-based, each row's
  ! columns strictly increasing, and every entry the sum of its triplets in
  ! triplet order (the first one, then the others added), found here on its
  ! own, bit for bit; no entry without a triplet.
  subroutine check_csr(m, rows, cols, vals, size_n, where)
    type(ntsf_csr), intent(in) :: m
    integer(c_int), intent(in) :: rows(:), cols(:)
    real(c_double), intent(in) :: vals(:)
    integer, intent(in) :: size_n
    character(len=*), intent(in) :: where
    real(c_double), allocatable :: acc(:)
    logical, allocatable :: seen(:)
    integer :: k, r, p, nnz
    logical :: ok

    ok = m%n == size_n .and. allocated(m%row_ptr) .and. allocated(m%col) .and. allocated(m%val)
    call check(ok, "the tangent's CSR is there and 2N x 2N "//where)
    if (.not. ok) return
    ok = size(m%row_ptr) == size_n + 1 .and. m%row_ptr(1) == 1
    if (ok) ok = all(m%row_ptr(2:) >= m%row_ptr(:size_n))
    nnz = m%row_ptr(size_n + 1) - 1
    ok = ok .and. size(m%col) == nnz .and. size(m%val) == nnz
    call check(ok, "row_ptr is 1-based and increasing, nnz = row_ptr(n + 1) - 1 "//where)
    if (.not. ok) return
    do r = 1, size_n
      do p = m%row_ptr(r) + 1, m%row_ptr(r + 1) - 1
        ok = ok .and. m%col(p) > m%col(p - 1)
      end do
    end do
    call check(ok .and. all(m%col >= 1 .and. m%col <= size_n), "columns 1-based and increasing in each row "//where)
    allocate (acc(nnz), seen(nnz))
    seen = .false.
    do k = 1, size(rows)
      p = position(m, rows(k) + 1, cols(k) + 1)
      if (p == 0) then
        ok = .false.
        exit
      end if
      if (seen(p)) then
        acc(p) = acc(p) + vals(k)
      else
        acc(p) = vals(k)
        seen(p) = .true.
      end if
    end do
    call check(ok .and. all(seen), "the CSR's entries are exactly the triplets' places "//where)
    if (ok .and. all(seen)) call check(same_bits(m%val, acc), "the CSR's values are the triplets' sums "//where)
  end subroutine check_csr

  integer function position(m, r, c)
    type(ntsf_csr), intent(in) :: m
    integer(c_int), intent(in) :: r, c
    integer :: p
    position = 0
    do p = m%row_ptr(r), m%row_ptr(r + 1) - 1
      if (m%col(p) == c) position = p
    end do
  end function position

  ! Scenes the C library refuses, through the module.
  subroutine check_scene_errors(good)
    type(ntsf_body), intent(in) :: good(:)
    type(ntsf_body), allocatable :: b(:)
    type(ntsf_body) :: none(0)
    type(ntsf_scene) :: s
    integer :: k, st

    ! A zero-length segment: a loop body with a node repeated.
    call reset(b, good)
    do k = 1, size(b)
      if (.not. allocated(b(k)%triangles)) exit
    end do
    if (k > size(b)) then
      ! every body a mesh: make the first one a plain loop of its nodes
      k = 1
      deallocate (b(1)%triangles)
      b(1)%nodes = b(1)%nodes(:, 1:3)
      b(1)%nodes(:, 1) = [0.0_c_double, 0.0_c_double]
      b(1)%nodes(:, 2) = [1.0_c_double, 0.0_c_double]
      b(1)%nodes(:, 3) = [0.0_c_double, 1.0_c_double]
    end if
    b(k)%nodes(:, 2) = b(k)%nodes(:, 1)
    call ntsf_scene_create(s, b, st, lx=lx, ly=ly, err=err)
    call check(st == NTS_EDEGENERATE_SEGMENT .and. err%body == k - 1, &
      "a repeated node is NTS_EDEGENERATE_SEGMENT of its body: "//ntsf_status_name(st))
    call check(ntsf_strerror(st) == "zero-length segment" .and. ntsf_status_name(st) == "degenerate_segment", &
      "ntsf_strerror and ntsf_status_name give C's message and name")
    call check(index(ntsf_error_message(err), "segment from node") > 0, &
      "the error message says which segment: "//ntsf_error_message(err))
    call check(ntsf_node_count(s) == 0, "a refused scene leaves the handle empty")

    ! A node index out of range: 0 is no node in 1-based indices.
    call reset(b, good)
    if (.not. allocated(b(1)%loop_nodes)) then
      b(1)%loop_nodes = [(k, k = 1, size(b(1)%nodes, 2))]
      if (allocated(b(1)%triangles)) deallocate (b(1)%triangles)
    end if
    b(1)%loop_nodes(2) = 0
    call ntsf_scene_create(s, b, st, lx=lx, ly=ly, err=err)
    call check(st == NTS_EINDEX_RANGE, "node index 0 is NTS_EINDEX_RANGE: "//ntsf_status_name(st))

    ! Arrays of the wrong shape are refused before C reads them.
    call reset(b, good)
    deallocate (b(1)%nodes)
    allocate (b(1)%nodes(3, 4))
    b(1)%nodes = 0
    call ntsf_scene_create(s, b, st, err=err)
    call check(st == NTS_EINVALID_ARGUMENT .and. err%body == 0 .and. &
      index(ntsf_error_message(err), "body 0: nodes must be shaped (2, node_count)") == 1, &
      "nodes shaped (3, n) are NTS_EINVALID_ARGUMENT: "//ntsf_error_message(err))

    ! loop_start past loop_nodes' end, before its start, or decreasing: refused
    ! before C reads loop_nodes (it read past the array's ends).
    do k = 1, 4
      call reset(b, good)
      if (allocated(b(1)%triangles)) deallocate (b(1)%triangles)
      b(1)%loop_nodes = [(st, st = 1, size(b(1)%nodes, 2))]
      select case (k)
      case (1)
        b(1)%loop_start = [1, size(b(1)%loop_nodes) + 4001]
      case (2)
        b(1)%loop_start = [0, size(b(1)%loop_nodes) + 1]
      case (3)
        b(1)%loop_start = [-100, size(b(1)%loop_nodes) + 1]
      case (4)
        b(1)%loop_start = [1, size(b(1)%loop_nodes) + 1, 2]
      end select
      call ntsf_scene_create(s, b, st, lx=lx, ly=ly, err=err)
      call check(st == NTS_EINVALID_ARGUMENT .and. index(ntsf_error_message(err), "loop_start must run from 1") > 0, &
        "a loop_start that does not fit loop_nodes is NTS_EINVALID_ARGUMENT: "//ntsf_error_message(err))
    end do

    call ntsf_scene_create(s, none, st, err=err)
    call check(st == NTS_EEMPTY_SCENE, "no bodies is NTS_EEMPTY_SCENE: "//ntsf_status_name(st))
    call ntsf_scene_destroy(s)
  end subroutine check_scene_errors

  ! b a fresh copy of good (allocate with source: gfortran 12 takes an
  ! assignment to an unallocated array of this type for a use of its bounds).
  subroutine reset(b, good)
    type(ntsf_body), allocatable, intent(inout) :: b(:)
    type(ntsf_body), intent(in) :: good(:)
    if (allocated(b)) deallocate (b)
    allocate (b, source=good)
  end subroutine reset

  ! The module's constants against the C tables, row for row.
  subroutine check_tables()
    integer(c_int) :: c(64)
    integer(c_int), parameter :: statuses(*) = [NTS_ENOMEM, NTS_EINVALID_ARGUMENT, NTS_EINVALID_OPTION, &
      NTS_EEMPTY_SCENE, NTS_ENO_NODES, NTS_ELOOP_TOO_SHORT, NTS_EINDEX_RANGE, NTS_ENODE_REUSED, NTS_ENONFINITE, &
      NTS_EDEGENERATE_SEGMENT, NTS_EZERO_AREA, NTS_ESPIKE, NTS_ENONMANIFOLD, NTS_EDEGENERATE_TRIANGLE, &
      NTS_EBOX_TOO_SMALL, NTS_ELIMIT, NTS_ENO_BOUNDARY, NTS_EINTERNAL, NTS_ERESHAPED, NTS_EOUT_OF_RANGE, &
      NTS_ECANCELLED, NTS_EINVALID_SURFACE, NTS_EINVALID_HISTORY]
    integer(c_int), parameter :: outputs(*) = [NTS_OUT_FORCES, NTS_OUT_ENERGY, NTS_OUT_VIRIAL, NTS_OUT_CONTACTS, &
      NTS_OUT_GAPS, NTS_OUT_STIFFNESS, NTS_OUT_PRESSURE, NTS_OUT_ALL]
    integer(c_int), parameter :: warnings(*) = [NTS_WARN_PENETRATION_BEYOND_RADIUS, NTS_WARN_PENETRATION_BEYOND_REACH]
    integer :: m

    m = ftest_status_table(c, size(c, kind=c_int))
    call check(m == size(statuses), "the module has every status code of base.h's NTS_ERRNO_MAP")
    if (m == size(statuses)) call check(all(c(1:m) == statuses), "its status codes are C's")
    m = ftest_output_table(c, size(c, kind=c_int))
    call check(m == size(outputs), "the module has every output of tables.h's NTS_OUTPUT_MAP")
    if (m == size(outputs)) call check(all(c(1:m) == outputs), "its output bits are C's")
    m = ftest_warning_table(c, size(c, kind=c_int))
    call check(m == size(warnings), "the module has every warning of NTS_WARNING_MAP")
    if (m == size(warnings)) call check(all(c(1:m) == warnings), "its warning codes are C's")
    call check(ntsf_status_name(NTS_OK) == "ok", "ntsf_status_name(NTS_OK) is ok")
    call ftest_kind_state_values(c(1:6))
    call check(all(c(1:6) == [NTS_KIND_SEGMENT, NTS_KIND_CORNER, NTS_KIND_VERTEX, NTS_FRICTIONLESS, NTS_STICK, &
      NTS_SLIP]), "its kinds and friction states are C's")
  end subroutine check_tables

  function c_text(chars) result(text)
    character(kind=c_char), intent(in) :: chars(:)
    character(len=:), allocatable :: text
    integer :: k
    text = ""
    do k = 1, size(chars)
      if (chars(k) == c_null_char) exit
      text = text//chars(k)
    end do
  end function c_text

  function ieee_nan() result(x)
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
    real(c_double) :: x
    x = ieee_value(x, ieee_quiet_nan)
  end function ieee_nan

end program test_fortran
