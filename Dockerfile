# calbench service image: the REST API and dashboard, with the simulated bench as default hardware.
FROM python:3.11-slim
ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1
WORKDIR /app
COPY pyproject.toml README.md ./
COPY api ./api
COPY bench ./bench
COPY db ./db
COPY station ./station
COPY drivers ./drivers
RUN pip install --no-cache-dir . && useradd --create-home calbench && mkdir -p /data && chown calbench /data
USER calbench
ENV CALBENCH_DATA_DIR=/data
EXPOSE 8000
# --sim: the simulated table and DAQ (real drivers on loopback); drop it and set
# CALBENCH_TABLE_URL / CALBENCH_DAQ_URL for a real bench. Alone, the service starts the bench
# agent as its child process; docker-compose.yml runs `calbench agent` as its own service.
CMD ["calbench", "serve", "--sim", "--host", "0.0.0.0", "--port", "8000"]
