! A solver's loop through the Fortran module (fortran/ntscontact.f90; issue 27,
! docs/benchmarks.md "In process: a solver's loop from Fortran"): the wall
! time of one step, ntsf_evaluate given every node's positions, in three ways
! on the same steps:
!   scratch  positions= alone: each step searched from scratch;
!   kept     with a kept candidate list (candidates=);
!   surface  kept, and only the loops' nodes read (surface_only=.true.).
! All three give the same answer (contact reads the loops' nodes alone, and a
! kept list never changes an answer); the program checks the forces equal, bit
! for bit, step by step (a hash of their bits). Two scenes: a packing of 64-node polygon disks (every
! node on a loop) and blocks of structured triangle meshes pressed together (a
! mesh's interior is most of its nodes). The motion is kept_bench's: every
! body along a direction of its own, each node a fifth as much along its own,
! back and forth, a step moving a node a tenth of what the default skin allows
! (a list built about every 10 steps). Rounds interleave the three ways (the
! order rotated); each way's figure is the mean over a round's steps, builds
! included; ratios are taken within a round, medians over the rounds printed.
!
!   build/bin/fortran_loop [rounds [steps]]
program fortran_loop
  use, intrinsic :: iso_c_binding, only: dp => c_double, c_int
  use, intrinsic :: iso_fortran_env, only: int64, output_unit, error_unit
  use ntscontact
  implicit none
  interface
    ! C's exit: a status without the "STOP 2" line that gfortran's stop
    ! writes (its QUIET= is Fortran 2018; the project builds to 2008)
    subroutine c_exit(status) bind(c, name="exit")
      import :: c_int
      integer(c_int), value :: status
    end subroutine c_exit
  end interface
  integer :: rounds, steps
  character(len=*), parameter :: usage_line = "usage: fortran_loop [rounds [steps]]  (default 5 rounds of 40 steps)"

  rounds = 5
  steps = 40
  call read_args()
  write (output_unit, '(a)') "| scene | nodes | surface nodes | contacts | builds a round | scratch ns/surface node | "// &
    "kept | surface | kept / scratch (median; range) | surface / scratch (median; range) |"
  write (output_unit, '(a)') "|---|---:|---:|---:|---:|---:|---:|---:|---|---|"
  call run_scene("packing 40x40 disks", .false., 40)
  call run_scene("blocks 13x13 meshes", .true., 13)

contains

  subroutine read_args()
    character(len=32) :: a
    integer :: st
    if (command_argument_count() >= 1) then
      call get_command_argument(1, a)
      if (a == "-h" .or. a == "--help") then
        write (output_unit, '(a)') usage_line
        stop
      end if
      read (a, *, iostat=st) rounds
      if (st /= 0 .or. rounds < 1) call usage("rounds: a positive integer, not '"//trim(a)//"'")
    end if
    if (command_argument_count() >= 2) then
      call get_command_argument(2, a)
      read (a, *, iostat=st) steps
      if (st /= 0 .or. steps < 1) call usage("steps: a positive integer, not '"//trim(a)//"'")
    end if
    if (command_argument_count() > 2) call usage("at most two arguments")
  end subroutine read_args

  ! A bad command line: what is wrong and the usage on stderr, exit 2 (no
  ! backtrace: error stop's would say "error" about the user's typing).
  subroutine usage(what)
    character(len=*), intent(in) :: what
    write (error_unit, '(a)') "fortran_loop: "//what
    write (error_unit, '(a)') usage_line
    flush (error_unit)
    call c_exit(2_c_int)
  end subroutine usage

  ! side x side bodies: 64-node disks of radius 1.02 two apart (pressed), or
  ! blocks of m x m nodes (a structured mesh of 2 (m - 1)^2 triangles) of side
  ! 1.02 one apart.
  subroutine make_bodies(b, mesh, side)
    type(ntsf_body), allocatable, intent(out) :: b(:)
    logical, intent(in) :: mesh
    integer, intent(in) :: side
    integer, parameter :: disk_nodes = 64, m = 20
    real(dp), parameter :: pi = 3.14159265358979323846_dp
    integer :: i, j, k, q, r, t
    real(dp) :: cx, cy, h
    allocate (b(side * side))
    do j = 0, side - 1
      do i = 0, side - 1
        k = j * side + i + 1
        if (.not. mesh) then
          cx = 2.0_dp * i
          cy = 2.0_dp * j
          allocate (b(k)%nodes(2, disk_nodes))
          do q = 1, disk_nodes
            b(k)%nodes(1, q) = cx + 1.02_dp * cos(2 * pi * (q - 1) / disk_nodes + 0.1_dp * k)
            b(k)%nodes(2, q) = cy + 1.02_dp * sin(2 * pi * (q - 1) / disk_nodes + 0.1_dp * k)
          end do
        else
          cx = 1.0_dp * i
          cy = 1.0_dp * j
          h = 1.02_dp / (m - 1)
          allocate (b(k)%nodes(2, m * m), b(k)%triangles(3, 2 * (m - 1) * (m - 1)))
          do r = 0, m - 1
            do q = 0, m - 1
              b(k)%nodes(:, r * m + q + 1) = [cx + h * q, cy + h * r]
            end do
          end do
          t = 0
          do r = 0, m - 2
            do q = 0, m - 2
              t = t + 1
              b(k)%triangles(:, t) = [r * m + q + 1, r * m + q + 2, (r + 1) * m + q + 2]
              t = t + 1
              b(k)%triangles(:, t) = [r * m + q + 1, (r + 1) * m + q + 2, (r + 1) * m + q + 1]
            end do
          end do
        end if
      end do
    end do
  end subroutine make_bodies

  ! kept_bench's directions: a unit vector per body plus a fifth of one per node.
  subroutine directions(b, dir)
    type(ntsf_body), intent(in) :: b(:)
    real(dp), intent(out) :: dir(:, :)
    integer :: k, q, at
    real(dp) :: a, c
    at = 0
    do k = 1, size(b)
      a = 2.399963_dp * k ! the golden angle: directions spread evenly
      do q = 1, size(b(k)%nodes, 2)
        at = at + 1
        c = 1.7_dp * at
        dir(:, at) = [cos(a) + 0.2_dp * cos(c), sin(a) + 0.2_dp * sin(c)]
      end do
    end do
  end subroutine directions

  subroutine run_scene(name, mesh, side)
    character(len=*), intent(in) :: name
    logical, intent(in) :: mesh
    integer, intent(in) :: side
    type(ntsf_body), allocatable :: b(:)
    type(ntsf_scene) :: s(3)
    type(ntsf_candidates) :: kc(3)
    type(ntsf_output) :: out(3)
    type(nts_options) :: opt
    type(nts_error) :: err
    type(nts_candidates_info) :: info
    integer(c_int), allocatable :: surf(:)
    real(dp), allocatable :: x0(:, :), dir(:, :), x(:, :)
    integer(int64), allocatable :: hash(:, :)
    real(dp) :: t(3, rounds), radius, amp, omega, a
    integer :: n, way, w, round, k, st, at, q, contacts
    integer(int64) :: builds0, builds

    call make_bodies(b, mesh, side)
    do way = 1, 3
      call ntsf_scene_create(s(way), b, st, err=err)
      if (st /= NTS_OK) then
        write (output_unit, '(3a)') name, ": ", ntsf_error_message(err)
        error stop 1
      end if
      if (way > 1) call ntsf_candidates_create(kc(way), st)
    end do
    n = ntsf_node_count(s(1))
    allocate (x0(2, n), dir(2, n), x(2, n), hash(steps, 3))
    at = 0
    do k = 1, size(b)
      do q = 1, size(b(k)%nodes, 2)
        at = at + 1
        x0(:, at) = b(k)%nodes(:, q)
      end do
    end do
    call directions(b, dir)
    call ntsf_surface_nodes(s(1), surf)
    opt = nts_default_options()
    opt%outputs = ior(ior(NTS_OUT_FORCES, NTS_OUT_ENERGY), NTS_OUT_VIRIAL)
    call ntsf_evaluate(s(1), opt, out(1), st, err)
    if (st /= NTS_OK) error stop "the first evaluation"
    radius = out(1)%summary%search_radius
    contacts = out(1)%summary%contacts
    amp = 0.5_dp * radius
    ! eq. (29) with alpha's default, K = 10 steps a build
    omega = 0.3_dp * radius / (3.0_dp + 2.0_dp * opt%alpha) / 10.0_dp / (1.2_dp * amp)
    builds0 = 0
    builds = 0
    do round = 1, rounds
      do w = 0, 2
        way = mod(round + w, 3) + 1 ! the order rotated from round to round
        if (way == 3) then
          info = ntsf_candidates_info(kc(3))
          builds0 = info%builds
        end if
        t(way, round) = 0
        do k = 1, steps
          a = amp * sin(omega * ((round - 1) * steps + k))
          x = x0 + a * dir
          t(way, round) = t(way, round) + step(s, kc, out, opt, way, x)
          hash(k, way) = bits_hash(out(way)%forces)
        end do
        if (way == 3) then
          info = ntsf_candidates_info(kc(3))
          builds = builds + (info%builds - builds0)
        end if
      end do
      if (any(hash(:, 2) /= hash(:, 1)) .or. any(hash(:, 3) /= hash(:, 1))) error stop "the forces differ"
    end do
    t = 1e9_dp * t / steps / size(surf)
    write (output_unit, '("| ", a, " | ", i0, " | ", i0, " | ", i0, " | ", f0.1, " | ", f0.1, " | ", f0.1, " | ", '// &
      'f0.1, " | ", a, " | ", a, " |")') name, n, size(surf), contacts, real(builds, dp) / rounds, median(t(1, :)), &
      median(t(2, :)), median(t(3, :)), ratio_text(t(2, :) / t(1, :)), ratio_text(t(3, :) / t(1, :))
    do way = 1, 3
      call ntsf_candidates_destroy(kc(way))
      call ntsf_scene_destroy(s(way))
    end do

  end subroutine run_scene

  ! One step of `way` at positions x: its wall time in seconds.
  real(dp) function step(s, kc, out, opt, way, x)
    type(ntsf_scene), intent(inout) :: s(3)
    type(ntsf_candidates), intent(inout) :: kc(3)
    type(ntsf_output), intent(inout) :: out(3)
    type(nts_options), intent(in) :: opt
    integer, intent(in) :: way
    real(dp), intent(in) :: x(:, :)
    type(nts_error) :: err
    integer(int64) :: c0, c1, rate
    integer :: st
    call system_clock(c0, rate)
    select case (way)
    case (1)
      call ntsf_evaluate(s(1), opt, out(1), st, err, positions=x)
    case (2)
      call ntsf_evaluate(s(2), opt, out(2), st, err, positions=x, candidates=kc(2))
    case default
      call ntsf_evaluate(s(3), opt, out(3), st, err, positions=x, candidates=kc(3), surface_only=.true.)
    end select
    call system_clock(c1)
    if (st /= NTS_OK) then
      write (output_unit, '(a, i0, 2a)') "way ", way, ": ", ntsf_error_message(err)
      error stop 1
    end if
    step = real(c1 - c0, dp) / real(rate, dp)
  end function step

  ! The forces' bits, hashed (any change of any bit changes it but by chance).
  integer(int64) function bits_hash(f)
    real(dp), intent(in) :: f(:, :)
    integer(int64) :: v(size(f))
    integer :: i
    v = transfer(f, v)
    bits_hash = 0
    do i = 1, size(v)
      bits_hash = ieor(ishftc(bits_hash, 7), v(i)) + i
    end do
  end function bits_hash

  real(dp) function median(v)
    real(dp), intent(in) :: v(:)
    real(dp) :: w(size(v)), tmp
    integer :: i, j
    w = v
    do i = 2, size(w) ! insertion sort: a handful of rounds
      tmp = w(i)
      j = i - 1
      do while (j >= 1)
        if (w(j) <= tmp) exit
        w(j + 1) = w(j)
        j = j - 1
      end do
      w(j + 1) = tmp
    end do
    median = w((size(w) + 1) / 2)
    if (mod(size(w), 2) == 0) median = 0.5_dp * (w(size(w) / 2) + w(size(w) / 2 + 1))
  end function median

  ! "median (min-max)" of the rounds' ratios.
  function ratio_text(v) result(text)
    real(dp), intent(in) :: v(:)
    character(len=:), allocatable :: text
    text = fixed3(median(v))//" ("//fixed3(minval(v))//"-"//fixed3(maxval(v))//")"
  end function ratio_text

  ! x with 3 decimals and its leading zero ("0.632": f0.3 drops it).
  function fixed3(x) result(text)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=32) :: buf
    write (buf, '(f32.3)') x
    text = trim(adjustl(buf))
  end function fixed3
end program fortran_loop
