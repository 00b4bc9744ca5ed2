/* Shim for NL-PartSol (2022): the code calls the Fortran LAPACK routines
   without the hidden string-length arguments that LAPACK >= 3.9.1's lapack.h
   declares, so declare them unprototyped, with the right return types. */
#ifndef NLPS_SHIM_LAPACKE_H
#define NLPS_SHIM_LAPACKE_H
double dlange_();
void dgecon_();
void dgetrf_();
void dgetri_();
void dgetrs_();
void dsyev_();
void dgeev_();
#endif
