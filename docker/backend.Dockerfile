# The HMI service serving the built frontend (the panel at /, the kiosk at /kiosk) on port 8000.
# Built from the repository root: docker build -f docker/backend.Dockerfile .

# Stage 1: the frontend, built with Node (nothing of it is needed at run time but dist/).
FROM node:20-bookworm-slim AS frontend
WORKDIR /src/frontend
COPY frontend/package.json frontend/package-lock.json ./
RUN npm ci --no-audit --no-fund
COPY frontend/ ./
RUN npm run build

# Stage 2, the wheels: the package's own, a cp311 platform wheel with the cyclic pump compiled by
# setuptools (gcc, libc's and Python's headers: the image has the latter), and its dependencies'.
FROM python:3.11-slim-bookworm AS wheel
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev \
    && rm -rf /var/lib/apt/lists/*
COPY backend/pyproject.toml backend/setup.py /src/backend/
COPY backend/src /src/backend/src
RUN pip wheel --wheel-dir /wheels /src/backend

# Stage 3: the Python service and the built frontend.
FROM python:3.11-slim-bookworm
ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /app
# The package from its platform wheel (stage "wheel": the cyclic pump compiled there, so this
# image has no compiler); COBOT_HMI_PUMP=native fails the build if the extension does not load.
COPY --from=wheel /wheels /wheels
RUN pip install --no-index --find-links /wheels cobot-hmi && rm -rf /wheels \
    && COBOT_HMI_PUMP=native python -m cobot_hmi.native \
    && useradd --system --create-home --home-dir /var/lib/cobot-hmi hmi
COPY --from=frontend /src/frontend/dist /app/frontend/dist

# Settings come from COBOT_HMI_* variables (docker-compose.yml sets them); these are defaults.
ENV COBOT_HMI_HOST=0.0.0.0 \
    COBOT_HMI_PORT=8000 \
    COBOT_HMI_STATE_DIR=/var/lib/cobot-hmi \
    COBOT_HMI_FRONTEND_DIR=/app/frontend/dist
USER hmi
VOLUME ["/var/lib/cobot-hmi"]
EXPOSE 8000/tcp 2222/udp
CMD ["cobot-hmi", "serve"]
